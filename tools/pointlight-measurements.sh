#!/usr/bin/env bash
# tools/pointlight-measurements.sh -- the point-light renderers against the independent
# reference (prt-reference --light, docs/reference.md "Point and directional lights"):
# the accuracy figures of docs/point-lights.md. For each scene it renders the reference
# on every k-th object pixel (--pixel-stride; the comparison is over those pixels), then
# every method at the same camera and compares it with prt-compare (linear relative
# RMSE and mean ratio). Scenes (the goal settings of docs/point-lights.md, the lights of the
# Keng table):
#   dragon   dragon_vrip_res2 (202,520 faces), 40 mm, Skimmilk, 1024 x 1024
#   bunny    bunny (75,408 faces), 40 mm, Marble, 1024 x 1024
#   armadillo (52,000 faces), 40 mm, Skin1, from behind, 1024 x 1024
#   tsis     dragon_vrip_res4 (11,102 faces), 30 mm, Skin2, 512 x 512 (the README's frame)
# Methods: cache (defaults) and jb (epsilon 0.05) over face centroids (Keng's samples, the
# default), jb over Poisson-disk samples at the spacing rule, and for the tsis scene
# texture-space sampling (hybrid, per vertex and per pixel) and brute (epsilon 0).
# Usage: tools/pointlight-measurements.sh [scene ...]   (default: all four)
#        REUSE=1 tools/pointlight-measurements.sh ...   re-tabulates the frames already there
# Needs the fetched meshes (tools/fetch-data.sh) and a Release build in $BUILD_DIR
# (default build/). About 35 minutes on 2 cores. Output: out/pointlight-measurements/,
# one <scene>.md table each, with the logs beside it.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${BUILD_DIR:-$root/build}
out=$root/out/pointlight-measurements
for tool in prt-reference prt-pointlight prt-compare; do
    [ -x "$build/bin/$tool" ] || { echo "pointlight-measurements: build first (tools/build.sh): $build/bin/$tool is missing" >&2; exit 1; }
done
mkdir -p "$out"
cd "$root"
m=data/meshes

# compare TEST REFERENCE: "rel. RMSE | mean ratio" of prt-compare's overall line.
compare() {
    "$build/bin/prt-compare" "$1" "$2" | awk '$1 == "overall" { printf "%.2f%% | %.4f", 100 * $2, $NF }'
}
# seconds LOG: the "wrote ... in X" total of a prt-pointlight run.
seconds() { grep -oE 'in [0-9.]+ s$|in [0-9]+ min [0-9]+ s$' "$1" | tail -1 | sed 's/^in //'; }

scene() {
    local name=$1 stride=$2
    shift 2
    local args=("$@")
    local dir=$out/$name
    mkdir -p "$dir"
    echo "== $name: reference (every $stride-th object pixel)" >&2
    [ "${REUSE:-0}" = 1 ] && [ -f "$dir/reference.exr" ] ||
        "$build/bin/prt-reference" "${args[@]}" --pixel-stride "$stride" -o "$dir/reference" > "$dir/reference.log" 2>&1
    {
        echo "# $name: prt-pointlight ${args[*]}"
        echo
        grep -E '^samples: [0-9]|discretisation' "$dir/reference.log" | sed 's/^/    /'
        echo
        echo "| method | options | rel. RMSE vs reference | mean ratio | run time |"
        echo "|---|---|---|---|---|"
    } > "$dir/table.md"
    run() {
        local label=$1 options=$2
        shift 2
        echo "== $name: $label" >&2
        # shellcheck disable=SC2086
        [ "${REUSE:-0}" = 1 ] && [ -f "$dir/$label.exr" ] ||
            "$build/bin/prt-pointlight" "${args[@]}" $options -o "$dir/$label" > "$dir/$label.log" 2>&1
        echo "| $label | \`$options\` | $(compare "$dir/$label.exr" "$dir/reference.exr") | $(seconds "$dir/$label.log") |" >> "$dir/table.md"
    }
    if [ "$name" = tsis ]; then
        run tsis-vertex "--method tsis --evaluate vertex --atlas-size 512 --rings 16 --ring-samples 16 --tsis-samples 1200"
        run tsis-pixel "--method tsis --evaluate pixel --atlas-size 512 --rings 16 --ring-samples 16 --tsis-samples 1200"
        run tsis-default "--method tsis"
    fi
    run cache "--method cache"
    run jb "--method jb"
    # The brute-force sum over 200K faces at 1024^2 would take ~20 min: small frames only.
    [ "$name" = tsis ] && run brute "--method brute"
    run jb-poisson "--method jb --samples poisson"
    cat "$dir/table.md"
    cp "$dir/table.md" "$out/$name.md"
}

scenes=("$@")
[ ${#scenes[@]} -gt 0 ] || scenes=(dragon bunny armadillo tsis)
for s in "${scenes[@]}"; do
    case $s in
        dragon) scene dragon 16 "$m/dragon_vrip_res2.ply.gz" --size-mm 40 -m Skimmilk --light point:30,40,20:0.01 \
                    -W 1024 -H 1024 --exposure -1 ;;
        bunny) scene bunny 16 "$m/bunny.off" --size-mm 40 -m Marble --light point:30,40,30:0.01 \
                   -W 1024 -H 1024 --exposure -1 ;;
        armadillo) scene armadillo 16 "$m/armadillo.off" --size-mm 40 -m Skin1 --azimuth 180 \
                       --light point:30,40,-30:0.01 -W 1024 -H 1024 --exposure -1 ;;
        tsis) scene tsis 4 "$m/dragon_vrip_res4.ply.gz" --size-mm 30 -m Skin2 --light point:-20,40,-60:0.04 \
                  -W 512 -H 512 ;;
        *) echo "pointlight-measurements: unknown scene '$s' (dragon, bunny, armadillo, tsis)" >&2; exit 1 ;;
    esac
done
