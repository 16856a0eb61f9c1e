#!/usr/bin/env python3
"""Sweeps options of `ours` over finished study folders: for each variant, `cvtrace reconstruct`
on every seed's streams against the scene's committed reference, and the mean relMSE relative to
the default. Reconstruction only (the renders are reused), so a sweep takes minutes.

    python3 research/tune_ours.py out/study/96 door-ajar glass-of-water
    VARIANTS="floor common 0.05" BASELINES=1 python3 research/tune_ours.py out/study/96 door-ajar

VARIANTS (comma-separated labels) limits the sweep; the first variant is always `default` (the
binary's defaults). BASELINES=1 also measures IDUW, CV (same binary, every seed) and the seeds'
real PT(2n) renders, and prints ours/IDUW, ours/CV and ours/PT(2n) for every variant.
"""
import math, os, re, subprocess, sys, tempfile

BIN = os.environ.get("BIN", "target/release/cvtrace")
VARIANTS = [
    ("default", []),
    ("ridge 1e-4", ["--ridge", "1e-4"]), ("ridge 1e-2", ["--ridge", "1e-2"]), ("ridge 1e-1", ["--ridge", "1e-1"]),
    ("k 16", ["--k", "16"]), ("k 36", ["--k", "36"]), ("k 49", ["--k", "49"]),
    ("k 36 window 13", ["--k", "36", "--search-window", "13"]), ("k 49 window 15", ["--k", "49", "--search-window", "15"]),
    ("window 7", ["--search-window", "7"]), ("window 15", ["--search-window", "15"]), ("window 21", ["--search-window", "21"]),
    ("penalty none", ["--penalty", "none"]), ("penalty max", ["--penalty", "max"]), ("penalty residual", ["--penalty", "residual"]),
    ("errors variance", ["--errors", "variance"]), ("errors cbf-residual", ["--errors", "cbf-residual"]),
    ("shared coefficients", ["--shared-coefficients"]),
    # The floor on the CRN covariance (docs/estimators.md) and cross-fitting.
    ("floor 0", ["--crn-floor", "0"]), ("floor common 0.02", ["--crn-floor", "0.02"]),
    ("floor common 0.05", ["--crn-floor", "0.05"]), ("floor common 0.1", ["--crn-floor", "0.1"]),
    ("floor common 0.25", ["--crn-floor", "0.25"]), ("floor common 0.5", ["--crn-floor", "0.5"]),
    ("floor common 1", ["--crn-floor", "1"]), ("floor common 2", ["--crn-floor", "2"]),
    ("floor common 1 crn", ["--crn-floor", "1", "--crn-floor-source", "crn"]),
    ("floor independent 1", ["--crn-floor", "1", "--crn-floor-mode", "independent"]),
    ("cross-fit", ["--folds", "halves"]),
    # The cross-bilateral filter behind the PT error estimates (--errors cbf).
    ("cbf exclude centre", ["--cbf-exclude-centre"]),
    ("cbf radius 2", ["--cbf-radius", "2"]), ("cbf radius 5", ["--cbf-radius", "5"]), ("cbf radius 7", ["--cbf-radius", "7"]),
    ("cbf sigma colour 0.1", ["--cbf-sigma-colour", "0.1"]), ("cbf sigma colour 0.5", ["--cbf-sigma-colour", "0.5"]),
    ("cbf sigma albedo 0.3", ["--cbf-sigma-albedo", "0.3"]), ("cbf sigma normal 0.5", ["--cbf-sigma-normal", "0.5"]),
    # The bias of in-sample coefficients: out-of-sample folds, or the low frequencies from PT.
    ("low-pass 0", ["--low-pass-sigma", "0"]), ("low-pass 2", ["--low-pass-sigma", "2"]), ("low-pass 4", ["--low-pass-sigma", "4"]),
    ("low-pass 8", ["--low-pass-sigma", "8"]), ("low-pass 16", ["--low-pass-sigma", "16"]),
    # The CV baseline (absolute relMSE; their ratios to `default` compare CV with ours).
    ("cv", ["--method", "cv"]), ("cv ridge 1", ["--method", "cv", "--cv-ridge", "1"]), ("cv ridge 3", ["--method", "cv", "--cv-ridge", "3"]),
    ("cv ridge 1 low-pass 8", ["--method", "cv", "--cv-ridge", "1", "--cv-low-pass-sigma", "8"]),
    ("cv pt-noise", ["--method", "cv", "--cv-pt-noise"]),
    ("cv pt-noise low-pass 8", ["--method", "cv", "--cv-pt-noise", "--cv-low-pass-sigma", "8"]),
    ("cv pt-noise ridge 0.01 low-pass 8", ["--method", "cv", "--cv-pt-noise", "--cv-ridge", "0.01", "--cv-low-pass-sigma", "8"]),
    ("cv centre out", ["--method", "cv", "--cv-centre", "out"]),
    ("cv classic", ["--method", "cv", "--cv-centre", "out", "--param", "cv.pt_noise=false", "--cv-low-pass-sigma", "0"]),
    ("cv cross-fit", ["--method", "cv", "--cv-folds", "halves"]),
    ("cv k 25", ["--method", "cv", "--k", "25", "--search-window", "11"]),
    ("cv ridge 0.1", ["--method", "cv", "--cv-ridge", "0.1"]),
    ("cv k 42 window 15", ["--method", "cv", "--k", "42", "--search-window", "15"]),
    ("cv k 56 window 15", ["--method", "cv", "--k", "56", "--search-window", "15"]),
    ("cv k 36 window 13", ["--method", "cv", "--k", "36", "--search-window", "13"]),
    ("cv k 64 window 15", ["--method", "cv", "--k", "64", "--search-window", "15"]),
    ("cv k 64 window 21", ["--method", "cv", "--k", "64", "--search-window", "21"]),
    ("cv k 49 window 21", ["--method", "cv", "--k", "49", "--search-window", "21"]),
    ("cv ridge 1 pt-noise", ["--method", "cv", "--cv-ridge", "1"]),
    ("cv window 5", ["--method", "cv", "--k", "25", "--select", "window", "--search-window", "5"]),
    # Radiance instead of illumination (the default divides both streams by the first-hit albedo).
    ("demodulate off", ["--demodulate", "off"]),
]


def relmse(streams, ref, extra, out):
    """relMSE of `ours` (or of the method a variant names with its own `--method`)."""
    method = extra[extra.index("--method") + 1] if "--method" in extra else "ours"
    pick = [] if "--method" in extra else ["--method", "ours"]
    cmd = [BIN, "--log", "warn", "reconstruct", streams, *pick, "--reference", ref, "-o", out, "--force", *extra]
    text = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    m = re.search(rf"^{re.escape(method)}\s+([0-9.eE+-]+)", text, re.M)
    return float(m.group(1))


def baseline(streams, ref, out_dir):
    """relMSE of iduw and cv on one seed's streams, and of its real PT(2n) render."""
    text = subprocess.run([BIN, "--log", "warn", "reconstruct", streams, "--method", "all", "--reference", ref, "-o", out_dir, "--force"],
                          check=True, capture_output=True, text=True).stdout
    got = {m: float(re.search(rf"^{m}\s+([0-9.eE+-]+)", text, re.M).group(1)) for m in ("iduw", "cv")}
    pt2n = streams.replace(".streams.exr", ".pt2n.exr")
    text = subprocess.run([BIN, "--log", "warn", "compare", "--reference", ref, pt2n], check=True, capture_output=True, text=True).stdout
    got["pt2n"] = float(re.search(r"pt2n\.exr\s+\d+\s+([0-9.eE+-]+)", text).group(1))
    return got


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
        # A bundled scene, else one of the validation set (measured, never tuned on).
        ref = next(f"{root}/{s}/scene.ref.exr" for root in ("scenes", "validation") if os.path.isdir(f"{root}/{s}"))
        print(f"{s:16} {len(seeds)} seeds", flush=True)
        for name, extra in variants:
            vals = [relmse(os.path.join(d, f), ref, extra, os.path.join(tmp, "x.exr")) for f in seeds]
            table[(s, name)] = sum(vals) / len(vals)
            print(f"{s:16} {name:22} {table[(s, name)]:.5g}", flush=True)
        if os.environ.get("BASELINES"):
            per = [baseline(os.path.join(d, f), ref, os.path.join(tmp, "all")) for f in seeds]
            for m in ("iduw", "cv", "pt2n"):
                table[(s, m)] = sum(p[m] for p in per) / len(per)
                print(f"{s:16} {m:22} {table[(s, m)]:.5g}", flush=True)
    print("\n| variant | " + " | ".join(scenes) + " | geometric mean |")
    print("|---|" + "---|" * (len(scenes) + 1))
    for name, _ in variants:
        r = [table[(s, name)] / table[(s, "default")] for s in scenes]
        g = math.exp(sum(map(math.log, r)) / len(r))
        print(f"| {name} | " + " | ".join(f"{(x - 1) * 100:+.1f}%" for x in r) + f" | {(g - 1) * 100:+.1f}% |")
    if os.environ.get("BASELINES"):
        print("\n| scene | " + " | ".join(f"{n}: relMSE, /IDUW, /CV, /PT(2n)" for n, _ in variants) + " |")
        print("|---|" + "---|" * len(variants))
        for s in scenes:
            cells = []
            for name, _ in variants:
                v = table[(s, name)]
                cells.append(f"{v:.4g}, {v / table[(s, 'iduw')]:.2f}, {v / table[(s, 'cv')]:.2f}, {v / table[(s, 'pt2n')]:.3f}")
            print(f"| {s} | " + " | ".join(cells) + " |")
        print("| baselines | " + "; ".join(f"{s}: IDUW {table[(s, 'iduw')]:.4g}, CV {table[(s, 'cv')]:.4g}, PT(2n) {table[(s, 'pt2n')]:.4g}" for s in scenes) + " |")


if __name__ == "__main__":
    main()
