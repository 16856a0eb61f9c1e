#!/usr/bin/env python3
"""The same scenes studied at two resolutions, side by side (docs/results.md, "Resolution"):

    python3 research/resolution_table.py out/study-validation/96 out/study-validation-1280x720/96

Per scene found in both folders and per resolution: the relMSE of PT(2n) and ours, the
reference's own noise ÷ ours, and the ratios ours/PT(2n), ours/IDUW, ours/CV and CV/PT(2n), each
with the reference's noise subtracted from both sides (a reference's noise adds the same constant
to every method's relMSE; at two resolutions the references differ, so only the subtracted ratios
compare). A ratio whose denominator or numerator the noise swallows is left out ("—").
"""
import glob, json, os, sys


def load(root):
    out = {}
    for f in sorted(glob.glob(os.path.join(root, "*", "results.json"))):
        for sc in json.load(open(f))["scenes"]:
            out[sc["name"]] = sc
    return out


def subtracted(m, a, b, noise):
    x, y = m[a]["relmse_mean"] - noise, m[b]["relmse_mean"] - noise
    return x / y if x > 0 and y > 0 else None


def main():
    low, high = load(sys.argv[1]), load(sys.argv[2])
    print("| scene | size | reference spp | PT(2n) | ours | ref. noise ÷ ours | ours/PT(2n) | ours/IDUW | ours/CV | CV/PT(2n) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name in sorted(set(low) & set(high)):
        for sc in (low[name], high[name]):
            m = {x["name"]: x for x in sc["methods"]}
            noise = sc["reference"].get("noise", {}).get("relmse") or 0.0
            cells = [f"{m[k]['relmse_mean']:.4g}" for k in ("pt2n", "ours")]
            cells.append(f"{noise / m['ours']['relmse_mean']:.2f}")
            for a, b in (("ours", "pt2n"), ("ours", "iduw"), ("ours", "cv"), ("cv", "pt2n")):
                r = subtracted(m, a, b, noise)
                cells.append(f"{r:.3f}" if r is not None else "—")
            print(f"| {name} | {sc['width']}×{sc['height']} | {sc['reference']['spp']} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
