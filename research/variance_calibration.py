"""Per scene: ours' predicted ÷ measured variance (weighted like relMSE, as the study computes it)
and its relMSE, for one set of `--param` options, reconstruction only over a study's renders:

    .cache/mitsuba-venv/bin/python research/variance_calibration.py out/study/32 mallows \
        "ours.variance_dof=mallows" cornell-box door-ajar engine glass-of-water

Needs numpy and Mitsuba's EXR reader (the venv `make compare-mitsuba` makes). Writes the
reconstructions to /tmp/cvtrace-calibration and the figures to LABEL-SPP.json there.
"""
import os, subprocess, sys, glob, json
import numpy as np
import mitsuba as mi
mi.set_variant("scalar_rgb")
BIN = os.environ.get("BIN", "target/release/cvtrace")
TMP = "/tmp/cvtrace-calibration"
os.makedirs(TMP, exist_ok=True)

def read(path):
    bmp = mi.Bitmap(path)
    layers = dict(bmp.split())
    def arr(name):
        return np.array(layers[name], dtype=np.float64)[..., :3]
    img = arr("<root>")
    var = arr("variance") if "variance" in layers else None
    return img, var

root, label, params = sys.argv[1], sys.argv[2], sys.argv[3].split()
out = {}
for s in sys.argv[4:]:
    spp = os.path.basename(os.path.normpath(root))
    d = os.path.join(root, s, f"spp{int(spp):05d}")
    ref, _ = read(f"scenes/{s}/scene.ref.exr")
    w = 1.0 / (ref.mean(axis=2) ** 2 + 0.01)
    imgs, preds, rel = [], [], []
    for f in sorted(glob.glob(os.path.join(d, "*.streams.exr"))):
        o = os.path.join(TMP, f"{label}-{s}.exr")
        args = []
        for p in params:
            args += ["--param", p]
        subprocess.run([BIN, "--log", "warn", "reconstruct", f, "--method", "ours", "-o", o, "--force", *args], check=True, stdout=subprocess.DEVNULL)
        img, var = read(o)
        imgs.append(img); preds.append((w[..., None] * var).mean())
        rel.append((w[..., None] * (img - ref) ** 2).mean())
    imgs = np.array(imgs)
    meas = (w[None, ..., None] * imgs.var(axis=0, ddof=1)).mean()
    out[s] = (np.mean(preds) / meas, np.mean(rel))
    print(f"{label:10} {s:16} cal {out[s][0]:.3f} relmse {out[s][1]:.5g}", flush=True)
json.dump(out, open(os.path.join(TMP, f"{label}-{spp}.json"), "w"))
