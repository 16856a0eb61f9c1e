#!/usr/bin/env python3
"""The denoiser tables of docs/results.md from finished studies.

    python3 research/denoiser_tables.py ROOT

ROOT holds one study folder per scene, `ROOT/<scene>/results.json`, each a study with an --spp
list (e.g. `cvtrace study ... --spp 32,96 --seeds 4 -o ROOT/<scene>`).

Prints Markdown: per spp value of the convergence points, relMSE ÷ PT(2n) of `ours`, `oidn`,
`pt2n-oidn` and `blend` per scene with geometric means, `blend` ÷ the better of `ours` and
`pt2n-oidn`, and squared bias; HDR-FLIP and time at the study's table spp (its largest); then
where `ours` crosses `pt2n-oidn` and where its error meets `pt2n-oidn`'s bias².
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


def points(scene):
    """{method: {spp per stream: convergence point}} (a method reads one stream's n spp or 2n)."""
    factor = {m["name"]: m["spp_total"] // scene["spp_per_stream"] for m in scene["methods"]}
    out = {}
    for p in scene["convergence"]:
        out.setdefault(p["method"], {})[p["spp_total"] // factor[p["method"]]] = p
    return out


def spps(scenes):
    return sorted({n for sc in scenes.values() for n in points(sc).get("ours", {})})


def geomean(values):
    values = [v for v in values if v is not None and v > 0]
    return math.exp(sum(math.log(v) for v in values) / len(values)) if values else float("nan")


def fmt(v, digits=3):
    return "–" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.{digits}g}"


def spp_table(scenes, n):
    rows = [s for s, sc in scenes.items() if all(n in points(sc).get(m, {}) for m in METHODS + ["pt2n"])]
    if not rows:
        return
    print(f"\n### {n} + {n} spp: relMSE ÷ PT(2n) ({len(rows)} scenes, {scenes[rows[0]]['seeds']} seeds)\n")
    print("| scene | ours | oidn (PT, n) | PT(2n) + OIDN | blend | blend ÷ min(ours, PT(2n)+OIDN) |")
    print("|---|---|---|---|---|---|")
    ratios, best, bias = {m: [] for m in METHODS}, [], {m: [] for m in METHODS}
    for s in rows:
        pts = points(scenes[s])
        rel = {m: pts[m][n]["relmse"] for m in METHODS + ["pt2n"]}
        for m in METHODS:
            ratios[m].append(rel[m] / rel["pt2n"])
            bias[m].append(pts[m][n].get("bias2"))
        best.append(rel["blend"] / min(rel["ours"], rel["pt2n-oidn"]))
        i = len(best) - 1
        print(f"| {s} | " + " | ".join(fmt(ratios[m][i]) for m in METHODS) + f" | {fmt(best[i])} |")
    print("| **geometric mean** | " + " | ".join(f"**{fmt(geomean(ratios[m]))}**" for m in METHODS)
          + f" | **{fmt(geomean(best))}** (max {fmt(max(best))}) |")
    print(f"\nblend better than both on {sum(1 for v in best if v < 1)} of {len(rows)} scenes; "
          f"geometric mean of blend ÷ PT(2n)+OIDN: {fmt(geomean([a / b for a, b in zip(ratios['blend'], ratios['pt2n-oidn'])]))}, "
          f"of ours ÷ PT(2n)+OIDN: {fmt(geomean([a / b for a, b in zip(ratios['ours'], ratios['pt2n-oidn'])]))}")
    # Every relMSE above holds the reference's own noise N (the study's estimate, the same for
    # every method); taking it out ranks the methods against the truth.
    print("\nThe same with the reference's noise N taken out, (relMSE − N) ÷ (relMSE of PT(2n) − N):\n")
    print("| scene | N ÷ PT(2n) | ours | oidn (PT, n) | PT(2n) + OIDN | blend | blend ÷ min(ours, PT(2n)+OIDN) |")
    print("|---|---|---|---|---|---|---|")
    clean, clean_best = {m: [] for m in METHODS}, []
    for s in rows:
        pts = points(scenes[s])
        noise = (scenes[s]["reference"].get("noise") or {}).get("relmse", 0.0)
        rel = {m: pts[m][n]["relmse"] - noise for m in METHODS + ["pt2n"]}
        for m in METHODS:
            clean[m].append(rel[m] / rel["pt2n"])
        clean_best.append(rel["blend"] / min(rel["ours"], rel["pt2n-oidn"]))
        print(f"| {s} | {fmt(noise / pts['pt2n'][n]['relmse'])} | " + " | ".join(fmt(clean[m][-1]) for m in METHODS)
              + f" | {fmt(clean_best[-1])} |")
    print("| **geometric mean** | | " + " | ".join(f"**{fmt(geomean(clean[m]))}**" for m in METHODS)
          + f" | **{fmt(geomean(clean_best))}** (max {fmt(max(clean_best))}) |")
    print("\nSquared bias (relative, ×10⁴; the study's estimate, which holds the reference's noise):\n")
    print("| scene | " + " | ".join(METHODS) + " |")
    print("|---|" + "---|" * len(METHODS))
    for i, s in enumerate(rows):
        print(f"| {s} | " + " | ".join(fmt(None if bias[m][i] is None else bias[m][i] * 1e4) for m in METHODS) + " |")
    pos = [(b, o) for b, o in zip(bias["blend"], bias["pt2n-oidn"]) if b and o and b > 0 and o > 0]
    print(f"\nbias² of blend ÷ PT(2n)+OIDN, geometric mean over the {len(pos)} scenes where both are positive: "
          f"{fmt(geomean([b / o for b, o in pos]))}")


def flip_and_time(scenes):
    spps = sorted({sc["spp_per_stream"] for sc in scenes.values()})
    print(f"\nHDR-FLIP (mean over seeds) at {', '.join(map(str, spps))} spp per stream:\n")
    print("| scene | PT(2n) | " + " | ".join(METHODS) + " |")
    print("|---|---|" + "---|" * len(METHODS))
    for s, sc in scenes.items():
        print(f"| {s} | " + " | ".join(fmt((method(sc, m) or {}).get("flip_mean")) for m in ["pt2n"] + METHODS) + " |")
    print("\nSeconds per image (render of what the method reads + reconstruction, 2 threads):\n")
    print("| scene | PT(2n) | " + " | ".join(METHODS) + " |")
    print("|---|---|" + "---|" * len(METHODS))
    for s, sc in scenes.items():
        t = {m: (method(sc, m) or {}).get("time_seconds") for m in ["pt2n"] + METHODS}
        print(f"| {s} | " + " | ".join(fmt(None if t[m] is None else t[m]["render"] + t[m]["reconstruct"]) for m in ["pt2n"] + METHODS) + " |")


def crossing(points_a, points_b):
    """The spp where a's relMSE falls below b's, by log-log interpolation between measured
    points, or extrapolated from the last two when it does not within the range."""
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
    if len(d) > 1 and d[-1][1] < d[-2][1]:
        (n0, d0), (n1, d1) = d[-2:]
        # The log ratio taken as linear in log spp beyond the last two points; beyond 100 times
        # the last point such a line says nothing.
        at = math.exp(math.log(n1) - d1 * (math.log(n1) - math.log(n0)) / (d1 - d0))
        return f"> {n1} (extrapolated ≈ {at:.0f})" if at < 100 * n1 else f"> {n1} (extrapolated: beyond {100 * n1})"
    return f"> {d[-1][0]}"


def reaches_floor(relmse, floor):
    """The spp where relMSE values `relmse` ({spp: value}, taken as c/spp from the largest) fall
    to `floor`: where an unbiased method's error meets a biased one's bias²."""
    if not relmse or not floor or floor <= 0:
        return None
    n = max(relmse)
    return n * relmse[n] / floor


def convergence(scenes):
    print("\n### Convergence: relMSE and bias² against total spp\n")
    print("The last two columns with the reference's noise N taken out of every relMSE and bias².\n")
    print("| scene | method | relMSE at n = " + ", ".join(map(str, spps(scenes)))
          + " spp per stream | bias² ×10⁴ | ours below PT(2n)+OIDN from n = | ours' error (as c/n) at PT(2n)+OIDN's last bias² from n = |")
    print("|---|---|---|---|---|---|")
    for s, sc in scenes.items():
        pts = points(sc)
        # Against the truth: the reference's noise taken out of every relMSE and bias².
        noise = (sc["reference"].get("noise") or {}).get("relmse", 0.0)
        rel = {m: {n: p["relmse"] - noise for n, p in pts.get(m, {}).items()} for m in METHODS}
        cross = crossing(rel["ours"], rel["pt2n-oidn"])
        oidn = pts.get("pt2n-oidn", {})
        floor_at = reaches_floor(rel["ours"], oidn[max(oidn)].get("bias2", 0.0) - noise if oidn else None)
        floor = "–" if floor_at is None else f"≈ {floor_at:.0f}"
        for m in ["ours", "pt2n-oidn", "blend"]:
            ns = sorted(pts.get(m, {}))
            r = ", ".join(fmt(pts[m][n]["relmse"]) for n in ns)
            b = ", ".join(fmt(None if pts[m][n].get("bias2") is None else pts[m][n]["bias2"] * 1e4) for n in ns)
            print(f"| {s} | {m} | {r} | {b} | {cross if m == 'ours' else ''} | {floor if m == 'ours' else ''} |")


def main(argv):
    if len(argv) != 2:
        sys.exit(__doc__)
    root = argv[1]
    scenes = {s: load(os.path.join(root, s, "results.json")) for s in sorted(os.listdir(root))
              if os.path.isfile(os.path.join(root, s, "results.json"))}
    scenes = {s: sc for s, sc in scenes.items() if method(sc, "blend")}
    for n in spps(scenes):
        spp_table(scenes, n)
    flip_and_time(scenes)
    if len(spps(scenes)) > 2:
        convergence(scenes)


if __name__ == "__main__":
    main(sys.argv)
