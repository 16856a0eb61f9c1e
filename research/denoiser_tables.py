#!/usr/bin/env python3
"""The denoiser tables of docs/results.md from finished studies.

    python3 research/denoiser_tables.py ROOT

ROOT holds one folder per spp value and scene, `ROOT/<spp>/<scene>/results.json` (a study at that
spp per stream, as scripts/study_scenes.sh lays them out), and optionally `ROOT/conv/<scene>/`,
a study with an --spp list whose convergence points give relMSE and bias² against spp.

Prints Markdown: per spp value, relMSE ÷ PT(2n) of `ours`, `oidn`, `pt2n-oidn` and `blend` per scene
with geometric means, `blend` ÷ the better of `ours` and `pt2n-oidn`, squared bias, HDR-FLIP, and
time; then the convergence and where `ours` crosses `pt2n-oidn`.
"""
import json
import math
import os
import sys

METHODS = ["ours", "oidn", "pt2n-oidn", "blend"]


def load(path):
    with open(path) as f:
        return json.load(f)["scenes"][0]


def method(scene, name):
    return next((m for m in scene["methods"] if m["name"] == name), None)


def geomean(values):
    values = [v for v in values if v is not None and v > 0]
    return math.exp(sum(math.log(v) for v in values) / len(values)) if values else float("nan")


def fmt(v, digits=3):
    return "–" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.{digits}g}"


def spp_table(root, spp):
    folder = os.path.join(root, spp)
    scenes = sorted(s for s in os.listdir(folder) if os.path.isfile(os.path.join(folder, s, "results.json")))
    rows, ratios, blend_vs_best, bias, flips, times = [], {m: [] for m in METHODS}, [], {m: [] for m in METHODS}, {}, {}
    for s in scenes:
        sc = load(os.path.join(folder, s, "results.json"))
        pt2n = method(sc, "pt2n")["relmse_mean"]
        r = {m: (method(sc, m) or {}).get("relmse_mean") for m in METHODS}
        for m in METHODS:
            ratios[m].append(r[m] / pt2n if r[m] else None)
            b = (method(sc, m) or {}).get("bias2")
            bias[m].append(b)
        best = min(r["ours"], r["pt2n-oidn"])
        blend_vs_best.append(r["blend"] / best)
        flips[s] = {m: (method(sc, m) or {}).get("flip_mean") for m in METHODS + ["pt2n"]}
        times[s] = {m: (method(sc, m) or {}).get("time_seconds") for m in METHODS + ["pt2n"]}
        rows.append(s)
    print(f"\n### {spp} + {spp} spp: relMSE ÷ PT(2n) ({len(rows)} scenes)\n")
    print("| scene | ours | oidn (PT, n) | PT(2n) + OIDN | blend | blend ÷ min(ours, PT(2n)+OIDN) |")
    print("|---|---|---|---|---|---|")
    for i, s in enumerate(rows):
        print(f"| {s} | " + " | ".join(fmt(ratios[m][i]) for m in METHODS) + f" | {fmt(blend_vs_best[i])} |")
    print("| **geometric mean** | " + " | ".join(f"**{fmt(geomean(ratios[m]))}**" for m in METHODS)
          + f" | **{fmt(geomean(blend_vs_best))}** (max {fmt(max(blend_vs_best))}) |")
    print(f"\nblend better than both on {sum(1 for v in blend_vs_best if v < 1)} of {len(rows)} scenes; "
          f"geometric mean of blend ÷ PT(2n)+OIDN: {fmt(geomean([a / b for a, b in zip(ratios['blend'], ratios['pt2n-oidn'])]))}, "
          f"of ours ÷ PT(2n)+OIDN: {fmt(geomean([a / b for a, b in zip(ratios['ours'], ratios['pt2n-oidn'])]))}")
    print("\nSquared bias (relative, ×10⁴; the study's estimate, which holds the reference's noise):\n")
    print("| scene | " + " | ".join(METHODS) + " |")
    print("|---|" + "---|" * len(METHODS))
    for i, s in enumerate(rows):
        print(f"| {s} | " + " | ".join(fmt(None if bias[m][i] is None else bias[m][i] * 1e4) for m in METHODS) + " |")
    pos = [(b, o) for b, o in zip(bias["blend"], bias["pt2n-oidn"]) if b and o and b > 0 and o > 0]
    print(f"\nbias² of blend ÷ PT(2n)+OIDN, geometric mean over the {len(pos)} scenes where both are positive: "
          f"{fmt(geomean([b / o for b, o in pos]))}")
    print("\nHDR-FLIP (mean over seeds):\n")
    print("| scene | PT(2n) | " + " | ".join(METHODS) + " |")
    print("|---|---|" + "---|" * len(METHODS))
    for s in rows:
        print(f"| {s} | {fmt(flips[s]['pt2n'])} | " + " | ".join(fmt(flips[s][m]) for m in METHODS) + " |")
    print("\nSeconds per image (render of what the method reads + reconstruction, 2 threads):\n")
    print("| scene | PT(2n) | " + " | ".join(METHODS) + " |")
    print("|---|---|" + "---|" * len(METHODS))
    for s in rows:
        t = times[s]
        print(f"| {s} | " + " | ".join(fmt(None if t[m] is None else t[m]["render"] + t[m]["reconstruct"]) for m in ["pt2n"] + METHODS) + " |")


def crossing(points_a, points_b):
    """The spp where a's relMSE falls below b's, by log-log interpolation between measured
    points; None if it does not within the range ('before' / 'after' say which end)."""
    common = sorted(set(points_a) & set(points_b))
    d = [(n, math.log(points_a[n]) - math.log(points_b[n])) for n in common]
    if not d:
        return "–"
    if d[0][1] < 0:
        return f"≤ {d[0][0]}"
    for (n0, d0), (n1, d1) in zip(d, d[1:]):
        if d0 >= 0 > d1:
            t = d0 / (d0 - d1)
            return f"≈ {math.exp(math.log(n0) + t * (math.log(n1) - math.log(n0))):.0f}"
    return f"> {d[-1][0]}"


def convergence(root):
    folder = os.path.join(root, "conv")
    if not os.path.isdir(folder):
        return
    scenes = sorted(s for s in os.listdir(folder) if os.path.isfile(os.path.join(folder, s, "results.json")))
    print("\n### Convergence: relMSE and bias² against total spp\n")
    print("| scene | method | " + " | ".join(["relMSE @ 2n = 64, 192, 768"]) + " | bias² ×10⁴ | ours below PT(2n)+OIDN from 2n = |")
    print("|---|---|---|---|---|")
    for s in scenes:
        sc = load(os.path.join(folder, s, "results.json"))
        pts = {}
        for p in sc["convergence"]:
            pts.setdefault(p["method"], {})[p["spp_total"]] = p
        rel = {m: {n: p["relmse"] for n, p in pts.get(m, {}).items()} for m in METHODS}
        cross = crossing(rel["ours"], rel["pt2n-oidn"])
        for m in ["ours", "pt2n-oidn", "blend"]:
            ns = sorted(pts.get(m, {}))
            r = ", ".join(fmt(pts[m][n]["relmse"]) for n in ns)
            b = ", ".join(fmt(None if pts[m][n].get("bias2") is None else pts[m][n]["bias2"] * 1e4) for n in ns)
            print(f"| {s} | {m} | {r} | {b} | {cross if m == 'ours' else ''} |")


def main(argv):
    if len(argv) != 2:
        sys.exit(__doc__)
    root = argv[1]
    for spp in sorted((d for d in os.listdir(root) if d.isdigit()), key=int):
        spp_table(root, spp)
    convergence(root)


if __name__ == "__main__":
    main(sys.argv)
