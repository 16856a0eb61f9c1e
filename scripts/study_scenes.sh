#!/usr/bin/env bash
# The estimator study over the bundled scenes (docs/results.md): for every scene, its committed
# reference (rendered here only if missing, resumable), a study at the largest spp of SPP_LIST with
# a convergence series over the others, one study per smaller spp value that reuses those renders,
# and the viewer plus a Markdown summary per spp value.
#
#   bash scripts/study_scenes.sh                      # every scene in scenes/
#   SCENES="door-ajar sponza" SEEDS=8 bash scripts/study_scenes.sh
#
# Everything is resumable: run it again after an interruption and finished renders are reused.
set -euo pipefail
cd "$(dirname "$0")/.."

BIN=${BIN:-target/release/cvtrace}
OUT=${OUT:-out/study}
SEEDS=${SEEDS:-4}
SPP_LIST=${SPP_LIST:-32,96}
BATCHES=${BATCHES:-16}
REF_SEED=${REF_SEED:-1000003}
THREADS=${THREADS:-}

scene_file() {
    for f in "scenes/$1/scene.gltf" "scenes/$1/scene.glb"; do
        [ -f "$f" ] && { echo "$f"; return; }
    done
    echo "study_scenes: scenes/$1 has no scene.gltf or scene.glb" >&2
    return 1
}

if [ -z "${SCENES:-}" ]; then
    SCENES=$(for d in scenes/*/; do d=${d%/}; [ -f "$d/scene.gltf" ] || [ -f "$d/scene.glb" ] && basename "$d"; done)
fi
[ -x "$BIN" ] || { echo "study_scenes: $BIN missing: run 'cargo build --release' first" >&2; exit 1; }
threads=()
[ -n "$THREADS" ] && threads=(--threads "$THREADS")

IFS=, read -r -a spps <<< "$SPP_LIST"
largest=${spps[-1]}
for s in $SCENES; do
    file=$(scene_file "$s")
    ref="scenes/$s/scene.ref.exr"
    if [ ! -f "$ref" ]; then
        # spp from the scene's sidecar (`reference_spp`); resumable through the checkpoint;
        # traced robustly (watertight), as the committed references were.
        "$BIN" "${threads[@]}" render "$file" --reference --traversal robust --seed "$REF_SEED" -o "$ref"
    fi
    main="$OUT/$largest/$s"
    "$BIN" "${threads[@]}" --log warn study "$file" --spp "$SPP_LIST" --seeds "$SEEDS" --batches "$BATCHES" \
        --reference "$ref" --ablations -o "$main"
    for n in "${spps[@]}"; do
        [ "$n" = "$largest" ] && continue
        dir="$OUT/$n/$s"
        mkdir -p "$dir"
        sub=$(printf 'spp%05d' "$n")
        [ -e "$dir/$sub" ] || ln -s "$(realpath "$main/$sub")" "$dir/$sub"
        "$BIN" "${threads[@]}" --log warn study "$file" --spp "$n" --seeds "$SEEDS" --batches "$BATCHES" \
            --reference "$ref" --ablations -o "$dir"
    done
done
for n in "${spps[@]}"; do
    "$BIN" report "$OUT/$n" -o "$OUT/report-$n" --markdown "$OUT/summary-$n.md" --force \
        --title "cvtrace: $n + $n spp"
done
