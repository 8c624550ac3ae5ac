#!/usr/bin/env bash
# The main job on the built-in default scene: set up, build, fetch the real data,
# precompute the Stanford bunny (30 mm, Marble, 6x32x32, the default blocks of 16
# vertices sharing 160 coefficients) and
# render it under real environments into out/, next to the brute-force reference.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
out=${OUT_DIR:-$root/out}
build=$root/build
mesh=$root/data/meshes/bunny.off
envs=(forest city)
t_start=$(date +%s)
step() { echo; echo "== demo: $* =="; }
timed() {
    local t0
    t0=$(date +%s)
    "$@"
    echo "demo: took $(( $(date +%s) - t0 )) s"
}

step "installing packages";  timed "$root/tools/setup.sh"
step "building (the four programs the demo runs)"
timed "$root/tools/build.sh" prt-precompute prt-relight prt-reference prt-compare
step "fetching data";        timed "$root/tools/fetch-data.sh"
mkdir -p "$out" "$out/compare"

step "precomputing the bunny (30 mm, Marble, 6x32x32, blocks of 16 vertices sharing 160 coefficients)"
timed "$build/bin/prt-precompute" "$mesh" --size-mm 30 --material Marble \
    --cubemap-size 32 --block-coefficients 160 -o "$out/bunny_marble.prt"

for env in "${envs[@]}"; do
    step "rendering under $env"
    timed "$build/bin/prt-relight" render "$mesh" -t "$out/bunny_marble.prt" \
        -e "$root/data/envmaps/$env.exr" -o "$out/bunny_$env"
    # The error a user sees: a 256 x 256 frame against prt-reference's independent
    # brute force (its own 250K samples and seed; docs/reference.md). The reference
    # takes about half a minute per environment on 2 cores (AVX2).
    step "brute-force reference under $env (256 x 256, independent samples)"
    timed "$build/bin/prt-relight" render "$mesh" -t "$out/bunny_marble.prt" \
        -e "$root/data/envmaps/$env.exr" -W 256 -H 256 -o "$out/compare/bunny_$env"
    timed "$build/bin/prt-reference" "$mesh" -t "$out/bunny_marble.prt" \
        -e "$root/data/envmaps/$env.exr" -W 256 -H 256 -o "$out/compare/bunny_${env}_reference"
    step "error of the precomputed render against the reference ($env)"
    "$build/bin/prt-compare" "$out/compare/bunny_$env.exr" "$out/compare/bunny_${env}_reference.exr" \
        --heatmap "$out/compare/bunny_${env}_error.png"
done

step "turntable under forest (12 frames)"
mkdir -p "$out/turntable"
timed "$build/bin/prt-relight" render "$mesh" -t "$out/bunny_marble.prt" \
    -e "$root/data/envmaps/forest.exr" --turntable 12 -o "$out/turntable/bunny"

echo
echo "demo: done in $(( $(date +%s) - t_start )) s. Frames are in $out:"
for env in "${envs[@]}"; do
    echo "  $out/bunny_$env.png (precomputed, 512 x 512)"
    echo "  $out/compare/bunny_$env.png, bunny_${env}_reference.png, bunny_${env}_error.png (256 x 256 against the reference)"
done
echo "  $out/turntable/bunny_0000.png ... bunny_0011.png"
