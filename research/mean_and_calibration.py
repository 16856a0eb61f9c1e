#!/usr/bin/env python3
"""Per scene, from finished studies: the image-mean offset of each estimator against the
reference (mean over seeds ± standard error, per channel, in %), whether `ours` is
mean-preserving (every channel's offset within 0.2% or within 3 standard errors of its own seed
noise, whichever is larger) and, for estimators that write a predicted-variance layer, predicted ÷
measured variance (both weighted like relMSE), with the largest single seed's share of the
predicted sum (near 1/seeds when no seed dominates; studies written before the per-seed figures
were recorded show –).

    python3 research/mean_and_calibration.py out/study/32 out/study/96

Prints one Markdown table per study root: the numbers of docs/estimators.md.
"""
import glob, json, os, sys

METHODS = ["pt", "iduw", "cv", "ours"]
MEAN_TOLERANCE = 0.002


def main():
    for root in sys.argv[1:]:
        rows = []
        for f in sorted(glob.glob(os.path.join(root, "*", "results.json"))):
            for sc in json.load(open(f))["scenes"]:
                m = {x["name"]: x for x in sc["methods"]}
                cells = []
                for k in METHODS:
                    off, se = m[k].get("image_mean_offset"), m[k].get("image_mean_offset_se") or [0, 0, 0]
                    cells.append(" ".join(f"{100 * a:+.2f}±{100 * b:.2f}" for a, b in zip(off, se)) if off else "–")
                o = m["ours"]
                off, se = o.get("image_mean_offset"), o.get("image_mean_offset_se")
                if off and se:
                    ok = all(abs(a) <= max(MEAN_TOLERANCE, 3 * b) for a, b in zip(off, se))
                    cells.append("yes" if ok else "**no**")
                else:
                    cells.append("–")
                cal = o["predicted_variance"] / o["variance"] if o.get("predicted_variance") and o.get("variance") else None
                cells.append(f"{cal:.3f}" if cal else "–")
                per_seed = o.get("predicted_variance_per_seed") or []
                cells.append(f"{max(per_seed) / sum(per_seed):.2f}" if len(per_seed) > 1 and sum(per_seed) > 0 else "–")
                rows.append((sc["name"], sc["spp_per_stream"], sc["seeds"], cells))
        if not rows:
            continue
        print(f"\n{root}: image mean − reference (% per channel R G B, ± standard error over seeds); ours' predicted ÷ measured variance\n")
        print("| scene | spp | seeds | " + " | ".join(METHODS) + " | ours within max(0.2%, 3 SE) | ours: predicted ÷ measured variance | largest seed's share of the predicted |")
        print("|---|---|---|" + "---|" * (len(METHODS) + 3))
        for name, spp, seeds, cells in rows:
            print(f"| {name} | {spp} + {spp} | {seeds} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
