#!/usr/bin/env python3
"""Scaling of cvtrace farm jobs to 1, 8, 64 and 512 nodes (docs/farm.md), from the measured cost
model of a part (research/farm_cost.sh). A small deterministic model, not a cluster simulator:

  part time   = fixed (start, scene load, BVH) + samples / (cores * rate) + write(part channels)
  job time    = waves * (dispatch + part time) + merge,   waves = ceil(parts / nodes)
  merge time  = fixed + parts * read(part channels) + write(output channels)   (one process)

A node has CORES cores and runs one part at a time with all of them (a frame), or one study cell
per core. Every part of a frame is a range of whole batches, so a frame has at most B parts.

  python3 research/farm_sim.py            # the tables of docs/farm.md
"""
import math

# --- measured with research/farm_cost.sh on the 2-core machine of docs/farm.md (load ~8) ---
RATE = 0.26e6           # samples per second per core: the bundled scenes' mean (0.52 M/s on 2 threads)
FIXED_S = 0.10          # process start + scene load + BVH build of a part (head: 106 ms load, engine: 47 ms BVH)
WRITE_S = 5.5e-8        # writing a part or stream file (EXR, ZIP): seconds per pixel and channel
READ_S = 2.2e-8         # the merge reading a part file: seconds per pixel and channel
# --- assumed ---
DISPATCH_S = 1.0        # Slurm: from a free node to the task running (a scheduling cycle)
CORES = 32              # cores per node of the scaled-up cluster


def stream_channels(batches):
    """Channels of a stream file of `batches` batches (picture, means, batches, features)."""
    return 4 + 6 * (batches + 1) + 7


def part_channels(batches):
    """Channels of a stream part of `batches` batches: its batch means and 13 x 8 sum pieces."""
    return 104 + 6 * batches


def frame(nodes, pixels, spp, batches, parts, tiles=False):
    """A stream render of `pixels` at spp + spp in `parts` parts on `nodes` nodes: ranges of whole
    batches (what cvtrace does), or with `tiles` image tiles of every batch (the alternative)."""
    if parts == 1:
        render = pixels * spp * 2 / (CORES * RATE)
        return DISPATCH_S + FIXED_S + render + WRITE_S * pixels * stream_channels(batches), render, 0.0, 0.0
    if tiles:
        px, channels = pixels / parts, stream_channels(batches)
        render = px * spp * 2 / (CORES * RATE)
    else:
        b = math.ceil(batches / parts)
        px, channels = pixels, part_channels(b)
        render = pixels * (spp // batches) * b * 2 / (CORES * RATE)
    part = FIXED_S + render + WRITE_S * px * channels
    waves = math.ceil(parts / nodes)
    merge = FIXED_S + parts * READ_S * px * channels + WRITE_S * pixels * stream_channels(batches)
    return waves * (DISPATCH_S + part) + merge, render, part, merge


def best_frame(nodes, pixels, spp, batches, tiles=False, most=None):
    counts = [p for p in range(1, (most or batches) + 1) if tiles or batches % p == 0]
    return min((frame(nodes, pixels, spp, batches, p, tiles) + (p,) for p in counts), key=lambda r: r[0])


def reference(nodes, pixels, spp, pass_spp, parts):
    """A reference of `pixels` at `spp` in `parts` parts of whole passes: a part file holds R, G, B
    and 3 x 8 sum pieces, the reference R, G, B."""
    if parts == 1:
        render = pixels * spp / (CORES * RATE)
        return DISPATCH_S + FIXED_S + render + WRITE_S * pixels * 3, render, 0.0, 0.0
    passes = math.ceil(spp / pass_spp)
    render = pixels * math.ceil(passes / parts) * pass_spp / (CORES * RATE)
    part = FIXED_S + render + WRITE_S * pixels * 27
    merge = FIXED_S + parts * READ_S * pixels * 27 + WRITE_S * pixels * 3
    return math.ceil(parts / nodes) * (DISPATCH_S + part) + merge, render, part, merge


def study(nodes, cells, pixels, spp, stats_s):
    """`cells` study cells (a stream render n + n and a PT(2n) render each): one cell per core,
    or one cell per node on all its cores, whichever ends first."""
    work = pixels * spp * 4 / RATE
    write = WRITE_S * pixels * (stream_channels(16) + 3)
    best = None
    for per_node, threads in ((CORES, 1), (1, CORES)):
        cell = 2 * FIXED_S + work / threads + write
        waves = math.ceil(cells / (nodes * per_node))
        t = waves * (DISPATCH_S + cell) + stats_s
        if best is None or t < best[0]:
            best = (t, cell, waves, threads)
    return best


def frame_table(title, pixels, spp, batches, tiles=False, most=None):
    print(f"{title}\n")
    print("| nodes | parts | part render s | part total s | merge s | frame s | speed-up |")
    print("|---|---|---|---|---|---|---|")
    one = best_frame(1, pixels, spp, batches, tiles, most)[0]
    for n in (1, 8, 64, 512):
        t, render, part, merge, p = best_frame(n, pixels, spp, batches, tiles, most)
        print(f"| {n} | {p} | {render:.1f} | {part:.1f} | {merge:.1f} | {t:.1f} | {one / t:.1f}x |")
    print()


def main():
    px = 1920 * 1080
    frame_table("1080p, 96 + 96 spp, 16 batches, parts of whole batches (the best part count for each cluster size):", px, 96, 16)
    frame_table("The same frame with 32 batches of 3 spp:", px, 96, 32)
    frame_table("The same frame split into image tiles instead (up to 512 tiles, every batch in each):", px, 96, 16, tiles=True, most=512)
    print("1080p, 96 + 96 spp, 16 batches, on 16 nodes, by the number of parts:\n")
    print("| parts | part render s | part total s | merge s | frame s |")
    print("|---|---|---|---|---|")
    for p in (1, 2, 4, 8, 16):
        t, render, part, merge = frame(16, px, 96, 16, p)
        print(f"| {p} | {render:.1f} | {part:.1f} | {merge:.1f} | {t:.1f} |")
    print()
    print("A 1080p reference of 16 384 spp in passes of 64 (256 passes), by nodes (parts = nodes, at most 256):\n")
    print("| nodes | parts | part render s | part total s | merge s | reference s | speed-up |")
    print("|---|---|---|---|---|---|---|")
    one = reference(1, px, 16384, 64, 1)[0]
    for n in (1, 8, 64, 512):
        p = min(n, 256)
        t, render, part, merge = reference(n, px, 16384, 64, p)
        print(f"| {n} | {p} | {render:.1f} | {part:.1f} | {merge:.1f} | {t:.1f} | {one / t:.1f}x |")
    print()
    # The study of docs/results.md: 8 scenes x 8 seeds at 96 + 96 spp, 320x180; the final job
    # reconstructs every estimator on every cell and scores them (about 3% of the renders' CPU
    # time, README), on one node.
    cells = 8 * 8
    pixels = 320 * 180
    stats = 0.03 * cells * pixels * 96 * 4 / RATE / CORES
    print("The 8-scene study (8 scenes x 8 seeds, 96 + 96 spp and PT(192), 320x180), a cell per task:\n")
    print("| nodes | threads per cell | cell s | waves | statistics s | study s | speed-up |")
    print("|---|---|---|---|---|---|---|")
    base = study(1, cells, pixels, 96, stats)[0]
    for n in (1, 8, 64, 512):
        t, cell, waves, threads = study(n, cells, pixels, 96, stats)
        print(f"| {n} | {threads} | {cell:.1f} | {waves} | {stats:.1f} | {t:.1f} | {base / t:.1f}x |")


if __name__ == "__main__":
    main()
