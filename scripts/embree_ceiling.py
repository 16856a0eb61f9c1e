#!/usr/bin/env python3
"""How close the render loop comes to Embree's own rate for its rays (docs/performance.md):

    python3 scripts/embree_ceiling.py [--runs N]

Runs `cargo bench -p cvtrace-embree --bench render` for the one-thread render loop of the Cornell box (256², max
depth 8) and for the bare Embree calls the renderer makes on the same scene (incoherent
nearest-hit and shadow rays one call each, camera rays in batches of 64), with both traversals.
The ceiling is the rate the rays alone would allow at the render's mix per sample; each run's
render is set against the same run's rays, because a shared VM's bare rates move between runs.
"""
import argparse, re, subprocess, sys

# Rays per sample of the bench's render (depth 8): nearest-hit continuations after the camera ray,
# the camera ray, and shadow rays (next-event estimation).
NEAREST, CAMERA, SHADOW = 3.44, 1.0, 2.60
FILTER = ("embree_single_thread/(intersect_random_incoherent|occluded_random_incoherent|"
          "intersect_camera_16spp_batches_of_64)(_high_fast)?$|1thread")
TRAVERSALS = (
    ("robust", "", "cornell_256_depth8_pt_4spp_1thread"),
    ("fast", "_high_fast", "cornell_256_depth8_pt_4spp_fast_traversal_1thread"),
)
UNIT = {"K": 1e-3, "M": 1.0, "G": 1e3}


def rates(output):
    """Criterion's middle throughput per benchmark, in M elements per second."""
    out = {}
    pattern = r"^(\S+)/(\S+)\s*\n\s*time:.*\n\s*thrpt:\s*\[\S+ \w?elem/s ([\d.]+) (\w?)elem/s"
    for m in re.finditer(pattern, output, re.M):
        out[m.group(2)] = float(m.group(3)) * UNIT.get(m.group(4), 1e-6)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=1)
    args = ap.parse_args()
    for run in range(1, args.runs + 1):
        bench = subprocess.run(["cargo", "bench", "-p", "cvtrace-embree", "--bench", "render", "--locked", "--", FILTER],
                               capture_output=True, text=True)
        if bench.returncode != 0:
            sys.exit(f"embree_ceiling: cargo bench failed:\n{bench.stderr[-2000:]}")
        r = rates(bench.stdout)
        for name, suffix, render in TRAVERSALS:
            needed = [f"intersect_random_incoherent{suffix}", f"occluded_random_incoherent{suffix}",
                      f"intersect_camera_16spp_batches_of_64{suffix}", render]
            missing = [n for n in needed if n not in r]
            if missing:
                sys.exit(f"embree_ceiling: the bench output has no {', '.join(missing)}")
            nearest, shadow, camera = (r[n] for n in needed[:3])
            us = NEAREST / nearest + CAMERA / camera + SHADOW / shadow
            print(f"run {run} {name:6s}: rays nearest {nearest:.2f} shadow {shadow:.2f} camera {camera:.2f} M/s;"
                  f" ceiling {1 / us:.3f} M samples/s; render {r[render]:.3f} M/s = {100 * r[render] * us:.1f}%")


if __name__ == "__main__":
    main()
