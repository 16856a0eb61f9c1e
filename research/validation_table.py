#!/usr/bin/env python3
"""The validation set's table for docs/results.md, from finished studies (defaults untouched):

    python3 research/validation_table.py out/study-validation/96

Per scene: relMSE of PT(2n), IDUW, CV and ours; ours/IDUW, ours/CV, ours/PT(2n) and CV/PT(2n)
(± the seeds' standard errors carried through the ratio); the reference's own noise ÷ the best
method's relMSE; and ours/PT(2n) with that noise subtracted from both (the reference's noise adds
the same constant to every method, so the raw ratios are biased towards 1). Geometric means over
the scenes found. Scenes without a finished study are listed as missing.
"""
import glob, json, math, os, sys


def ratio(a, b):
    r = a["relmse_mean"] / b["relmse_mean"]
    rel = lambda m: (m.get("relmse_se") or 0.0) / m["relmse_mean"]
    return r, r * math.hypot(rel(a), rel(b))


def main():
    root = sys.argv[1]
    rows, logs = [], {k: [] for k in ("oi", "oc", "op", "cp", "opc")}
    for f in sorted(glob.glob(os.path.join(root, "*", "results.json"))):
        for sc in json.load(open(f))["scenes"]:
            m = {x["name"]: x for x in sc["methods"]}
            noise = sc["reference"].get("noise", {}).get("relmse") or 0.0
            best = min(m[k]["relmse_mean"] for k in ("iduw", "cv", "ours", "pt2n"))
            oi, oc, op, cp = ratio(m["ours"], m["iduw"]), ratio(m["ours"], m["cv"]), ratio(m["ours"], m["pt2n"]), ratio(m["cv"], m["pt2n"])
            # When the reference's own noise reaches ours' relMSE, the subtraction has
            # nothing left to measure: the cell says so and the scene stays out of that mean.
            opc = None
            if noise < m["ours"]["relmse_mean"]:
                opc = (m["ours"]["relmse_mean"] - noise) / (m["pt2n"]["relmse_mean"] - noise)
                logs["opc"].append(math.log(opc))
            for k, v in zip(("oi", "oc", "op", "cp"), (oi, oc, op, cp)):
                logs[k].append(math.log(v[0]))
            cells = [f"{m[k]['relmse_mean']:.4g}" for k in ("pt2n", "iduw", "cv", "ours")]
            cells += [f"{r:.3f} ± {e:.3f}" for r, e in (oi, oc, op, cp)]
            cells += [f"{noise / best:.2f}", f"{opc:.3f}" if opc is not None else "— (reference too noisy)"]
            rows.append((sc["name"], sc["spp_per_stream"], sc["seeds"], sc["reference"]["spp"], cells))
    print("| scene | spp | seeds | reference spp | PT(2n) | IDUW | CV | ours | ours/IDUW | ours/CV | ours/PT(2n) | CV/PT(2n) | ref. noise ÷ best | ours/PT(2n), ref. noise subtracted |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name, spp, seeds, ref_spp, cells in rows:
        print(f"| {name} | {spp} + {spp} | {seeds} | {ref_spp} | " + " | ".join(cells) + " |")
    if rows:
        g = {k: math.exp(sum(v) / len(v)) if v else float("nan") for k, v in logs.items()}
        print(f"| **geometric mean ({len(rows)} scenes)** | | | | | | | | {g['oi']:.3f} | {g['oc']:.3f} | {g['op']:.3f} | {g['cp']:.3f} | | {g['opc']:.3f} |")
    have = {os.path.basename(os.path.dirname(f)) for f in glob.glob(os.path.join(root, "*", "results.json"))}
    missing = sorted(d for d in os.listdir("validation") if os.path.isdir(os.path.join("validation", d)) and d not in have)
    if missing:
        print(f"\nNot yet studied: {', '.join(missing)}.")


if __name__ == "__main__":
    main()
