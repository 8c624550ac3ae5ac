#!/usr/bin/env bash
# Relative RMSE of prt-relight render against prt-reference for the default scene
# (bunny, 30 mm, Marble, 6x32x32) at several coefficient counts per vertex, under
# the given environments. Reuses reference images in OUT if present (delete them when
# switching SAME_SAMPLES). SAME_SAMPLES=1: the reference on the precomputation's own
# samples (prt-reference --same-samples), as the old table of docs/performance.md.
# Usage: [SAME_SAMPLES=1] tools/coefficient-table.sh [OUT_DIR] [env ...]
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
out=${1:-$root/out/table}; shift || true
envs=("${@:-forest city}")
[ $# -gt 0 ] || envs=(forest city)
build=$root/build
mesh=$root/data/meshes/bunny.off
mkdir -p "$out"
for env in "${envs[@]}"; do
    ref=$out/ref_$env
    same=()
    [ "${SAME_SAMPLES:-0}" = 1 ] && same=(--same-samples)
    [ -f "$ref.exr" ] || "$build/bin/prt-reference" "$mesh" -t "$root/out/bunny_marble.prt" \
        -e "$root/data/envmaps/$env.exr" "${same[@]}" -o "$ref" >/dev/null 2>&1
done
printf '| coefficients | %s |\n' "$(IFS='|'; echo "${envs[*]}" | sed 's/|/ | /g')"
for k in 32 64 128 256; do
    "$build/bin/prt-precompute" "$mesh" --size-mm 30 --material Marble -k "$k" -q \
        -o "$out/bunny_k$k.prt" >/dev/null 2>&1
    row="| $k |"
    for env in "${envs[@]}"; do
        "$build/bin/prt-relight" render "$mesh" -t "$out/bunny_k$k.prt" -e "$root/data/envmaps/$env.exr" \
            -o "$out/k${k}_$env" >/dev/null 2>&1
        err=$("$build/bin/prt-compare" "$out/k${k}_$env.exr" "$ref.exr" | awk '/^overall/ {print $2}')
        row="$row $err |"
    done
    echo "$row"
done
