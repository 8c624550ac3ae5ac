#!/usr/bin/env bash
# The editable file against full precomputes (docs/editable-transport.md, "Accuracy"):
# one editable file per mesh (made at 30 mm, Marble, its defaults), relit as each
# material and size, against a full precompute of that material and size with the
# editable file's samples, seed and terms per vertex pinned, so only the radial basis
# (and the 8-bit Haar values of the profiles) differs. Renders 256 x 256, prt-compare's
# relative RMSE over the object. Prints two markdown tables:
#   materials: every measured material with absorption at 30 mm on the bunny, forest;
#   sizes: the most and the least translucent (Skimmilk, Ketchup) at 15 and 60 mm on the
#          bunny and the dragon res3, forest and city.
# With REFERENCE=1 also each of Marble and Ketchup (30 mm, bunny, forest) against
# prt-reference: the editable and the full file's error, and their difference.
# With BLOCKS=M both files are blocked with M indices per block (--block-coefficients M;
# the editable one with nested lists), the per-vertex terms they are chosen from pinned.
#
#   tools/editable-accuracy.sh [materials|sizes|all]      (default all)
#
# Outputs in ${OUT:-out/editable-accuracy} (with BLOCKS=M: out/editable-accuracy-blocked-M). Files already there are REUSED when newer than
# the build's prt-precompute (say REUSE=0 to redo them); each reuse is printed.
# About 15 minutes on 2 cores from nothing.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${PRT_BUILD_DIR:-$root/build}"
what="${1:-all}"
case "$what" in materials | sizes | all) ;; *) echo "usage: tools/editable-accuracy.sh [materials|sizes|all]" >&2; exit 2 ;; esac
blocks="${BLOCKS:-0}"
[[ "$blocks" =~ ^[0-9]+$ ]] || { echo "editable-accuracy: BLOCKS must be a count of indices per block, got '$blocks'" >&2; exit 2; }
blockArgs=()
[[ "$blocks" -gt 0 ]] && blockArgs=(--block-coefficients "$blocks")
default_out="$root/out/editable-accuracy"
[[ "$blocks" -gt 0 ]] && default_out="$root/out/editable-accuracy-blocked-$blocks"
out="${OUT:-$default_out}"
mkdir -p "$out"
bin="$build/bin"
for t in prt-precompute prt-relight prt-compare prt-reference; do
    [[ -x "$bin/$t" ]] || { echo "editable-accuracy: missing $bin/$t (build first)" >&2; exit 1; }
done
data="$root/data"
reuse="${REUSE:-1}"

# fresh FILE: whether FILE must be (re)made.
fresh() {
    if [[ "$reuse" == 1 && -s "$1" && "$1" -nt "$bin/prt-precompute" ]]; then
        echo "  (reusing $1)" >&2
        return 1
    fi
    return 0
}
# "x.xxx%" of prt-compare TEST REF's overall row.
rmse() { "$bin/prt-compare" "$1" "$2" | awk '$1 == "overall" { printf "%.3f%%", 100 * $2 }'; }

# editable MESH_NAME MESH: the editable file of a mesh; sets ed, samples, terms.
editable() {
    ed="$out/$1_editable.prt"
    if fresh "$ed"; then
        echo "editable precompute of $1 ..." >&2
        "$bin/prt-precompute" "$2" -o "$ed" --size-mm 30 -m Marble --editable "${blockArgs[@]}" --summary-json "$out/$1_editable.json" \
            > "$out/$1_editable.log" 2>&1 || { echo "editable-accuracy: see $out/$1_editable.log" >&2; exit 1; }
    fi
    samples=$(python3 -c "import json, sys; print(json.load(open(sys.argv[1]))['summary']['samples'])" "$out/$1_editable.json")
    terms=$(python3 -c "import json, sys; print(json.load(open(sys.argv[1]))['settings']['coefficients'])" "$out/$1_editable.json")
}

# cell MESH_NAME MESH MATERIAL SIZE ENV: "editable vs full" of one case; sets e_img, f_img.
cell() {
    local name="$1" mesh="$2" m="$3" size="$4" env="$5"
    local full="$out/${name}_${m}_${size}_full.prt"
    if fresh "$full"; then
        "$bin/prt-precompute" "$mesh" -o "$full" --size-mm "$size" -m "$m" --samples "$samples" -k "$terms" "${blockArgs[@]}" \
            > "$full.log" 2>&1 || { echo "editable-accuracy: see $full.log" >&2; exit 1; }
    fi
    e_img="$out/${name}_${m}_${size}_${env}_editable"
    f_img="$out/${name}_${m}_${size}_${env}_full"
    "$bin/prt-relight" render "$mesh" -t "$ed" -e "$data/envmaps/$env.exr" -W 256 -H 256 --material "$m" \
        --size-mm "$size" -o "$e_img" > "$e_img.log" 2>&1
    "$bin/prt-relight" render "$mesh" -t "$full" -e "$data/envmaps/$env.exr" -W 256 -H 256 -o "$f_img" > "$f_img.log" 2>&1
    rmse "$e_img.exr" "$f_img.exr"
}

bunny="$data/meshes/bunny.off"
if [[ "$what" != sizes ]]; then
    editable bunny "$bunny"
    echo "materials (bunny, 30 mm, forest; editable: $samples samples, $terms terms per vertex, blocks: $blocks)"
    echo
    echo "| material | editable vs full |"
    echo "|---|---|"
    for m in Marble Apple Cream Wholemilk Skin2 Skimmilk Skin1 Potato Chicken1 Chicken2 Ketchup; do
        echo "| $m | $(cell bunny "$bunny" "$m" 30 forest) |"
    done
    if [[ "${REFERENCE:-0}" == 1 ]]; then
        echo
        echo "| material | editable vs reference | full vs reference | difference (points) |"
        echo "|---|---|---|---|"
        for m in Marble Ketchup; do
            ref="$out/bunny_${m}_30_forest_reference"
            if fresh "$ref.exr"; then
                "$bin/prt-reference" "$bunny" -t "$out/bunny_${m}_30_full.prt" -e "$data/envmaps/forest.exr" \
                    -W 256 -H 256 -o "$ref" > "$ref.txt" 2>&1
            fi
            a=$(rmse "$out/bunny_${m}_30_forest_editable.exr" "$ref.exr")
            b=$(rmse "$out/bunny_${m}_30_forest_full.exr" "$ref.exr")
            echo "| $m | $a | $b | $(python3 -c "import sys; print('%+.2f' % (float(sys.argv[1][:-1]) - float(sys.argv[2][:-1])))" "$a" "$b") |"
        done
    fi
    echo
fi
if [[ "$what" != materials ]]; then
    echo "sizes (editable files made at 30 mm, Marble)"
    echo
    echo "| mesh | material | 15 mm forest | 15 mm city | 60 mm forest | 60 mm city |"
    echo "|---|---|---|---|---|---|"
    for mesh in bunny dragon_res3; do
        path="$bunny"
        [[ "$mesh" == dragon_res3 ]] && path="$data/meshes/dragon_vrip_res3.ply.gz"
        editable "$mesh" "$path"
        for m in Skimmilk Ketchup; do
            row="| $mesh | $m"
            for size in 15 60; do
                for env in forest city; do row="$row | $(cell "$mesh" "$path" "$m" "$size" "$env")"; done
            done
            echo "$row |"
        done
    done
fi
