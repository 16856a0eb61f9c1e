"""Another renderer's samples reconstructed by cvtrace: Mitsuba 3 renders the PT and CRN streams
of its Cornell box, cvtrace's `ours` reconstructs the image from them, and both are scored
against a Mitsuba reference beside Mitsuba's own path tracer at the same total samples.

    python crates/python/examples/mitsuba_crn.py [--size 64] [--spp 32] [--batches 8] [--seed 1]

Mitsuba 3 from PyPI, variant `scalar_rgb` (no LLVM needed), its `path` integrator for every
stream:

- PT: `mi.render(scene, spp=n/B, seed=...)` once per batch, each with its own seed, so that
  every pixel and every batch has independent random numbers.
- CRN: sample `s` of every pixel must use the same random numbers. A loop in Python hands
  Mitsuba's `path` integrator, for every pixel, a sampler seeded by the sample index `s`
  alone, which also draws the camera ray's sub-pixel position: every pixel's sample `s` then
  uses the same random sequence. (`mi.render` cannot do that: it seeds its sampler per pixel.)
- Features: Mitsuba's `aov` integrator (albedo, shading normal, depth), for `ours`'s
  demodulation and error filter.

Then `cvtrace.Streams.from_arrays(pt_batches, crn_batches, spp=n)` and `cvtrace.reconstruct`.
"""

from __future__ import annotations

import argparse

import numpy as np

import cvtrace

MAX_DEPTH = 8


def load_scene(size: int):
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    mi.set_log_level(mi.LogLevel.Error)
    scene = mi.cornell_box()
    # A box filter: a sample counts only in its own pixel, as in cvtrace's streams.
    scene["sensor"]["film"].update({"width": size, "height": size, "rfilter": {"type": "box"}})
    scene["integrator"] = {"type": "path", "max_depth": MAX_DEPTH}
    return mi, mi.load_dict(scene)


def crn_stream(mi, scene, spp: int, batches: int, seed: int) -> np.ndarray:
    """The CRN stream's batch means, (B, H, W, 3): for sample `s` of every pixel, Mitsuba's
    `path` integrator gets a sampler seeded by `s` alone (a fresh copy per pixel), which also
    draws the sub-pixel position and the lens sample: every pixel's sample `s` uses the same
    random numbers, as in cvtrace's own CRN stream."""
    sensor = scene.sensors()[0]
    width, height = sensor.film().crop_size()
    path = mi.load_dict({"type": "path", "max_depth": MAX_DEPTH})
    sampler = mi.load_dict({"type": "independent"})
    per_batch = spp // batches
    out = np.zeros((batches, height, width, 3))
    for s in range(spp):
        for y in range(height):
            for x in range(width):
                common = sampler.clone()
                common.seed(seed + s)
                jitter = common.next_2d()
                position = mi.Point2f((x + jitter[0]) / width, (y + jitter[1]) / height)
                ray, weight = sensor.sample_ray(0.0, common.next_1d(), position, common.next_2d())
                radiance, _, _ = path.sample(scene, common, ray)
                out[s // per_batch, y, x] += np.array(radiance) * np.array(weight)
    return (out / per_batch).astype(np.float32)


def render_streams(mi, scene, spp: int, batches: int, seed: int) -> cvtrace.Streams:
    """The PT and CRN streams of `scene`, `spp` samples each in `batches` batches, with the
    first-hit features (albedo, shading normal, depth) of Mitsuba's `aov` integrator."""
    if spp % batches:
        raise ValueError(f"batches={batches} does not divide spp={spp}")
    # Seeds far apart for the PT batches, the CRN samples and the features of each run.
    base = seed * 1_000_003
    pt = np.stack([np.array(mi.render(scene, spp=spp // batches, seed=base + b)) for b in range(batches)])
    crn = crn_stream(mi, scene, spp, batches, base + 500_000)
    aov = mi.load_dict({"type": "aov", "aovs": "albedo:albedo,nn:sh_normal,dd:depth"})
    features = np.array(mi.render(scene, integrator=aov, spp=spp, seed=base + 900_000))
    return cvtrace.Streams.from_arrays(
        pt,
        crn,
        albedo=features[..., 0:3],
        normal=features[..., 3:6],
        depth=features[..., 6],
        spp=spp,
        seed=seed,
        max_depth=MAX_DEPTH,
        scene="mitsuba:cornell_box",
    )


def compare(size: int = 64, spp: int = 32, batches: int = 8, seed: int = 1, reference_spp: int = 1024) -> dict[str, float]:
    """relMSE against a Mitsuba reference of cvtrace's estimators on Mitsuba's streams (`spp`
    per stream, `2 spp` in all) and of Mitsuba's own path tracer with `2 spp`."""
    mi, scene = load_scene(size)
    reference = np.array(mi.render(scene, spp=reference_spp, seed=2_000_000_000))
    streams = render_streams(mi, scene, spp, batches, seed)
    mitsuba_pt = np.array(mi.render(scene, spp=2 * spp, seed=1_000_000_000 + seed))
    scores = {f"mitsuba pt ({2 * spp} spp)": cvtrace.relmse(mitsuba_pt, reference)}
    for method in ("ours", "cv", "average", "pt", "crn"):
        scores[method] = cvtrace.relmse(cvtrace.reconstruct(streams, method), reference)
    return scores


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--spp", type=int, default=32, help="samples per pixel of each stream")
    ap.add_argument("--batches", type=int, default=8)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--reference-spp", type=int, default=1024)
    a = ap.parse_args()
    scores = compare(a.size, a.spp, a.batches, a.seed, a.reference_spp)
    pt = scores[f"mitsuba pt ({2 * a.spp} spp)"]
    print(f"Mitsuba 3 Cornell box {a.size}x{a.size}, {a.spp} + {a.spp} spp, seed {a.seed}, reference {a.reference_spp} spp")
    for name, value in scores.items():
        print(f"  {name:<22} relMSE {value:.5f}   ({value / pt:.3f} x Mitsuba PT)")


if __name__ == "__main__":
    main()
