#!/usr/bin/env bash
# Single scattering alone against the refracted-path reference, for several transport
# files of one mesh (e.g. the last files of tools/ss-bench.sh: every vertex and sites):
# each file's single scattering is rendered as the renderers do by default (along the
# eye's path) and compared with ONE prt-reference frame (Monte Carlo along the true
# refracted view ray with the exact phase: no cubemap, no truncation, no vertices, its
# own random numbers), so the files' figures share the reference's noise alike.
# Prints each file's relative RMSE and mean ratio, the reference's noise floor, and
# each file against the first. docs/single-scattering.md, "Sites".
#
#   tools/ss-accuracy.sh MESH ENVIRONMENT SIZE FILE.prt [FILE.prt ...]
#
# SIZE: the frame's width = height in pixels (e.g. 128). Outputs go to
# ${OUT:-out/ss-accuracy}; the reference is kept there and reused when it is newer than
# the mesh, the environment and the first file. SS_SAMPLES (256) path samples per pixel.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${PRT_BUILD_DIR:-$root/build}"
usage="usage: tools/ss-accuracy.sh MESH ENVIRONMENT SIZE FILE.prt [FILE.prt ...]"
mesh="${1:?$usage}" env="${2:?$usage}" size="${3:?$usage}"
shift 3
[[ $# -ge 1 ]] || { echo "$usage" >&2; exit 2; }
for f in "$mesh" "$env" "$@" "$build/bin/prt-relight" "$build/bin/prt-reference" "$build/bin/prt-compare"; do
    [[ -e "$f" ]] || { echo "ss-accuracy: missing $f" >&2; exit 1; }
done
out="${OUT:-$root/out/ss-accuracy}"
mkdir -p "$out"
ref="$out/reference"
if [[ ! "$ref.exr" -nt "$1" || ! "$ref.exr" -nt "$mesh" || ! "$ref.exr" -nt "$env" ]]; then
    "$build/bin/prt-reference" "$mesh" -t "$1" -e "$env" -W "$size" -H "$size" --components ss \
        --ss-path refracted --ss-samples "${SS_SAMPLES:-256}" -o "$ref" > "$out/reference.txt" 2>&1
fi
echo "reference: $ref.exr, $(grep -m1 -o 'expected relative RMSE from Monte Carlo noise [0-9.e+-]*%' "$out/reference.txt" || echo 'noise: see reference.txt')"
# "rel RMSE x%, mean ratio y" of the overall row of prt-compare A B.
compare() {
    "$build/bin/prt-compare" "$1" "$2" | awk '$1 == "overall" { printf "rel RMSE %.3f%%, mean ratio %.4f\n", 100 * $2, $NF }'
}
k=0
for f in "$@"; do
    "$build/bin/prt-relight" render "$mesh" -t "$f" -e "$env" -W "$size" -H "$size" --components ss \
        -o "$out/file$k" > "$out/file$k.txt" 2>&1
    echo "$f"
    echo "  against the reference: $(compare "$out/file$k.exr" "$ref.exr")"
    [[ $k -gt 0 ]] && echo "  against the first file: $(compare "$out/file$k.exr" "$out/file0.exr")"
    k=$((k + 1))
done
