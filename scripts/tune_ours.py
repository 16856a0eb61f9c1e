#!/usr/bin/env python3
"""Sweeps options of `ours` over finished study folders: for each variant, `cvtrace reconstruct`
on every seed's streams against the scene's committed reference, and the mean relMSE relative to
the default. Reconstruction only (the renders are reused), so a sweep takes minutes.

    python3 scripts/tune_ours.py out/study/96 door-ajar glass-of-water
"""
import math, os, re, subprocess, sys, tempfile

BIN = os.environ.get("BIN", "target/release/cvtrace")
VARIANTS = [
    ("default", []),
    ("ridge 1e-4", ["--ridge", "1e-4"]), ("ridge 1e-2", ["--ridge", "1e-2"]), ("ridge 1e-1", ["--ridge", "1e-1"]),
    ("k 16", ["--k", "16"]), ("k 36", ["--k", "36"]), ("k 49", ["--k", "49"]),
    ("window 7", ["--search-window", "7"]), ("window 15", ["--search-window", "15"]), ("window 21", ["--search-window", "21"]),
    ("penalty none", ["--penalty", "none"]), ("penalty max", ["--penalty", "max"]), ("penalty residual", ["--penalty", "residual"]),
    ("errors variance", ["--errors", "variance"]), ("errors cbf-residual", ["--errors", "cbf-residual"]),
    ("shared coefficients", ["--shared-coefficients"]),
]


def relmse(streams, ref, extra, out):
    cmd = [BIN, "--log", "warn", "reconstruct", streams, "--method", "ours", "--reference", ref, "-o", out, "--force", *extra]
    text = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    m = re.search(r"^ours\s+([0-9.eE+-]+)", text, re.M)
    return float(m.group(1))


def main():
    study_root, scenes = sys.argv[1], sys.argv[2:]
    spp = os.path.basename(os.path.normpath(study_root))
    only = os.environ.get("VARIANTS")
    variants = [v for v in VARIANTS if not only or v[0] == "default" or v[0] in only.split(",")]
    tmp = tempfile.mkdtemp()
    table = {}
    for s in scenes:
        d = os.path.join(study_root, s, f"spp{int(spp):05d}")
        seeds = sorted(f for f in os.listdir(d) if f.endswith(".streams.exr"))
        ref = f"scenes/{s}/scene.ref.exr"
        for name, extra in variants:
            vals = [relmse(os.path.join(d, f), ref, extra, os.path.join(tmp, "x.exr")) for f in seeds]
            table[(s, name)] = sum(vals) / len(vals)
            print(f"{s:16} {name:22} {table[(s, name)]:.5g}", flush=True)
    print("\n| variant | " + " | ".join(scenes) + " | geometric mean |")
    print("|---|" + "---|" * (len(scenes) + 1))
    for name, _ in variants:
        r = [table[(s, name)] / table[(s, "default")] for s in scenes]
        g = math.exp(sum(map(math.log, r)) / len(r))
        print(f"| {name} | " + " | ".join(f"{(x - 1) * 100:+.1f}%" for x in r) + f" | {(g - 1) * 100:+.1f}% |")


if __name__ == "__main__":
    main()
