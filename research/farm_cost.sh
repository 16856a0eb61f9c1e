#!/usr/bin/env bash
# The cost model of a farm part, measured (docs/farm.md): for each bundled scene, a stream render
# in PARTS parts of whole batches, each part's process time split into what does not shrink with
# the part (process start, scene load, BVH build, writing the part file) and its render, the size
# of a part file, the merge time, and a check that the merge equals the one-shot render.
#
#   bash research/farm_cost.sh [BIN] [SPP] [BATCHES] [PARTS] [SCENES...]
# defaults: target/release/cvtrace 16 8 4, every scene in scenes/. Prints a Markdown table.
set -euo pipefail

bin=${1:-target/release/cvtrace}
spp=${2:-16}
batches=${3:-8}
parts=${4:-4}
shift $(($# < 4 ? $# : 4))
scenes=("$@")
if ((${#scenes[@]} == 0)); then
    for s in scenes/*/scene.gltf; do scenes+=("$s"); done
fi
bin=$(realpath "$bin")
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

now() { date +%s.%N; }
calc() { awk "BEGIN { print $* }"; }
# The milliseconds of the first log line matching $2 in file $1 (`... in 12.3 ms`).
ms() { grep -m1 "$2" "$1" | sed -E 's/.* in ([0-9.]+) ms.*/\1/'; }
# The render seconds of file $1 (`render: N samples in S s`).
render_s() { grep -m1 "render: " "$1" | sed -E 's/.* samples in ([0-9.]+) s.*/\1/'; }

echo "| scene | size | one-shot s | part wall s (mean) | part render s | load ms | BVH ms | write ms | fixed share | part file MB | merge s | identical |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|"
for scene in "${scenes[@]}"; do
    name=$(basename "$(dirname "$scene")")
    t0=$(now)
    "$bin" --log info render "$scene" --spp "$spp" --batches "$batches" -o "$tmp/one.exr" --force 2>"$tmp/one.log"
    t1=$(now)
    size=$(grep -m1 -oE "rendering [0-9]+x[0-9]+" "$tmp/one.log" | cut -d' ' -f2)
    wall=0 rend=0 load=0 bvh=0 write=0 bytes=0
    for ((i = 0; i < parts; i++)); do
        a=$(now)
        "$bin" --log info render "$scene" --spp "$spp" --batches "$batches" --part "$i/$parts" -o "$tmp/part$i.exr" --force 2>"$tmp/part$i.log"
        b=$(now)
        wall=$(calc "$wall + $b - $a")
        rend=$(calc "$rend + $(render_s "$tmp/part$i.log")")
        load=$(calc "$load + $(ms "$tmp/part$i.log" "loaded ")")
        bvh=$(calc "$bvh + $(ms "$tmp/part$i.log" "built the Embree BVH")")
        write=$(calc "$write + $(ms "$tmp/part$i.log" "wrote ")")
        bytes=$((bytes + $(stat -c %s "$tmp/part$i.exr")))
    done
    a=$(now)
    "$bin" --log warn merge "$tmp"/part*.exr -o "$tmp/merged.exr" --force
    b=$(now)
    same=no
    cmp -s "$tmp/one.exr" "$tmp/merged.exr" && same=yes
    printf "| %s | %s | %.2f | %.2f | %.2f | %.0f | %.0f | %.0f | %.0f%% | %.1f | %.2f | %s |\n" \
        "$name" "$size" "$(calc "$t1 - $t0")" "$(calc "$wall / $parts")" "$(calc "$rend / $parts")" \
        "$(calc "$load / $parts")" "$(calc "$bvh / $parts")" "$(calc "$write / $parts")" \
        "$(calc "100 * ($wall - $rend) / $wall")" "$(calc "$bytes / $parts / 1000000")" "$(calc "$b - $a")" "$same"
    rm -f "$tmp"/*.exr
done
