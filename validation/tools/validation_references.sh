#!/bin/bash
# Render the validation set's references, resumably: each reference checkpoints after every pass,
# so running this again after an interruption continues where it stopped.
#   validation/tools/validation_references.sh [FRACTION] [CVTRACE]
# FRACTION divides each sidecar's reference_spp (4: the quarter references of the plan in
# validation/README.md; 1: the full ones, reached from a quarter one with --extend).
# Scenes go cheapest first (the speed table in validation/README.md), so that finished references
# accumulate early; SCENES="a b" renders only those. References are traced robustly (watertight),
# as the committed ones were, so that --extend continues them. SIZE=WxH renders at another
# resolution than the sidecar's, into scene.ref-WxH.exr (the resolution study of
# validation/README.md); SPP=N replaces reference_spp/FRACTION; THREADS=N limits the render threads.
set -euo pipefail
cd "$(dirname "$0")/../.."
fraction=${1:-4}
cvtrace=${2:-target/release/cvtrace}
# The seed of the bundled references (scripts/study_scenes.sh): far from the study seeds 0, 1, ...
seed=${REF_SEED:-1000003}
size=${SIZE:-}
size_args=()
suffix=
if [ -n "$size" ]; then
    size_args=(--width "${size%x*}" --height "${size#*x}")
    suffix=-$size
fi
threads=()
[ -n "${THREADS:-}" ] && threads=(--threads "$THREADS")
scenes=${SCENES:-"bunny-glass city-etoile city-san-francisco city-munich bounce-interior pbr-grid
        caustics armadillo-room thin-blinds small-emitters"}
for s in $scenes; do
    dir=validation/$s
    full=$(sed -n 's/^reference_spp *= *\([0-9]*\).*/\1/p' "$dir/scene.cvtrace.toml")
    spp=${SPP:-$((full / fraction))}
    out=$dir/scene.ref$suffix.exr
    if [ -f "$out" ]; then
        have=$(oiiotool --info -v "$out" 2>/dev/null | sed -n 's/.*cvtrace.spp: *\([0-9]*\).*/\1/p' | head -1)
        if [ -n "$have" ] && [ "$have" -ge "$spp" ]; then
            echo "$s: reference of $have spp exists"
            continue
        fi
        echo "$s: extending the reference from ${have:-?} to $spp spp"
        "$cvtrace" render "$dir/scene.gltf" --reference --traversal robust --seed "$seed" --spp "$spp" "${size_args[@]}" "${threads[@]}" --extend -o "$out"
    else
        echo "$s: rendering a reference of $spp spp"
        "$cvtrace" render "$dir/scene.gltf" --reference --traversal robust --seed "$seed" --spp "$spp" "${size_args[@]}" "${threads[@]}" -o "$out"
    fi
done
