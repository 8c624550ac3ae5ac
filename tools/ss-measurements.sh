#!/usr/bin/env bash
# Reproduces the single-scattering measurements of docs/single-scattering.md: the
# Stanford bunny at 30 mm, Marble, multiple + single scattering with g = 0
# (isotropic) and g = +0.25 / -0.25 (K = 4 SVD terms); precompute times and file
# sizes, relight time per frame, relative RMSE of ms + ss against prt-reference under
# forest, and the pair of single-scattering frames like Wang et al. 2005, Fig. 3.
#
#   tools/ss-measurements.sh [output-dir]      (default out/ss; ~45 min on 2 cores)
#   OLD_RULE=1 tools/ss-measurements.sh ...      the rule the doc's bunny table was measured
#                                                with: 16 midpoint path samples, every
#                                                direction traced, visibility by a second ray
#
# Up-to-date transport files are not recomputed (prt-precompute's input digest), so
# a second run only re-renders. Needs a build (tools/build.sh) and the data
# (tools/fetch-data.sh).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${PRT_BUILD_DIR:-$root/build}"
out="${1:-$root/out/ss}"
mesh="$root/data/meshes/bunny.off"
forest="$root/data/envmaps/forest.exr"
for f in "$mesh" "$forest" "$build/bin/prt-precompute" "$build/bin/prt-reference"; do
    [[ -e "$f" ]] || { echo "ss-measurements: missing $f (run tools/build.sh and tools/fetch-data.sh)" >&2; exit 1; }
done
mkdir -p "$out"
rule=()
[ "${OLD_RULE:-0}" = 1 ] && rule=(--path-quadrature midpoint --path-samples 16 --ss-direction-stride 1 --ss-visibility ray)

for g in 0 0.25 -0.25; do
    echo "== precompute g = $g"
    "$build/bin/prt-precompute" "$mesh" --size-mm 30 --material Marble \
        --components ms,ss --g "$g" --phase-terms 4 "${rule[@]}" -o "$out/bunny_g$g.prt" -q \
        | tee "$out/bunny_g$g.summary.txt"
    ls -l "$out/bunny_g$g.prt"
done

# Relight + reference + comparison under forest (ms + ss), 256 x 256.
for g in 0 0.25; do
    echo "== forest, g = $g"
    "$build/bin/prt-relight" render "$mesh" -t "$out/bunny_g$g.prt" -e "$forest" \
        -W 256 -H 256 -o "$out/bunny_g${g}_forest" | tee "$out/bunny_g${g}_forest.render.txt"
    "$build/bin/prt-reference" "$mesh" -t "$out/bunny_g$g.prt" -e "$forest" -W 256 -H 256 \
        --components ms,ss --ss-samples 256 --component-images \
        -o "$out/bunny_g${g}_forest_reference" | tee "$out/bunny_g${g}_forest.reference.txt"
    "$build/bin/prt-compare" "$out/bunny_g${g}_forest.exr" "$out/bunny_g${g}_forest_reference.exr" \
        --heatmap "$out/bunny_g${g}_forest_error.png" | tee "$out/bunny_g${g}_forest.compare.txt"
done

# Relight time per frame at 512 x 512 (diffuse + isotropic ss; K = 4 terms).
for g in 0 0.25; do
    echo "== relight timing, g = $g"
    "$build/bin/prt-relight" render "$mesh" -t "$out/bunny_g$g.prt" -e "$forest" \
        --env-spin 12 -o "$out/timing_g$g/bunny" | tail -n 2
done

# Fig. 3: single scattering alone, g = +0.25 and g = -0.25, backlit by the sunset
# (sun behind the bunny), same camera and exposure.
for g in 0.25 -0.25; do
    "$build/bin/prt-relight" render "$mesh" -t "$out/bunny_g$g.prt" \
        -e "$root/data/envmaps/sunset.exr" --env-rotation "${FIG3_ROTATION:-0}" \
        --components ss --exposure "${FIG3_EXPOSURE:-1}" -W 384 -H 384 -o "$out/fig3_g$g"
done
echo "done: results in $out"
