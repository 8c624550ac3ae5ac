#!/usr/bin/env bash
# The error budget of docs/fidelity.md: the bunny (30 mm) precomputed with the defaults,
# with one approximation relaxed at a time, with the sun split (prt-relight render --sun-split)
# at three thresholds and two cell sizes, and swept over coefficients per vertex and
# over sample density; each rendered at 256 x 256 under forest and city (or the
# environments --envs names) and compared with prt-reference's independent render (made
# once per environment, about half a minute each, kept in OUT_DIR). Prints one line per
# run and writes OUT_DIR/MATERIAL_MESH.tsv (material, kind, name, option value,
# environment, rel RMSE, precompute seconds) for tools/plot_fidelity.py.
#   tools/fidelity-budget.sh [--reuse] [--envs "E1 E2 ..."] [MATERIAL] [OUT_DIR] [MESH] [SIZE_MM]
#   (defaults: Marble, out/budget, data/meshes/bunny.off, 30; environments are stems in
#   data/envmaps, "all" for every one). --reuse keeps the references and transport files
#   OUT_DIR already holds (from an earlier run of the same commit: not checked) and says
#   so for each; without it everything is made again.
set -euo pipefail
reuse=0
envs="forest city"
while [[ ${1:-} == -* ]]; do
    case $1 in
        --reuse) reuse=1 ;;
        --envs) [[ $# -ge 2 ]] || { echo "fidelity-budget: --envs needs a list" >&2; exit 2; }; envs=$2; shift ;;
        -h|--help) sed -n '2,14p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
        *) echo "fidelity-budget: unknown option '$1' (see --help)" >&2; exit 2 ;;
    esac
    shift
done
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${BUILD_DIR:-$root/build}
mat=${1:-Marble}
out=${2:-$root/out/budget}
mesh=${3:-$root/data/meshes/bunny.off}
size=${4:-30}
tag=${mat}_$(basename "$mesh" | cut -d. -f1)
if [[ $envs == all ]]; then
    envs=$(for e in "$root"/data/envmaps/*.exr; do basename "$e" .exr; done | tr '\n' ' ')
fi
for env in $envs; do
    [[ -f $root/data/envmaps/$env.exr ]] || { echo "fidelity-budget: no environment data/envmaps/$env.exr" >&2; exit 1; }
done
mkdir -p "$out"
tsv=$out/$tag.tsv
printf 'material\tkind\tname\tvalue\tenvironment\trel_rmse\tprecompute_s\n' > "$tsv"
precompute() { "$build/bin/prt-precompute" "$mesh" --size-mm "$size" --material "$mat" --force "$@"; }

precompute -o "$out/${tag}_default.prt" > "$out/${tag}_default.log"
for env in $envs; do
    ref=$out/ref_${tag}_$env
    if [[ $reuse == 1 && -f $ref.exr ]]; then
        echo "fidelity-budget: reusing $ref.exr (--reuse)"
    else
        "$build/bin/prt-reference" "$mesh" -t "$out/${tag}_default.prt" \
            -e "$root/data/envmaps/$env.exr" -W 256 -H 256 -o "$ref" > "$ref.log"
    fi
done

spacing=$(awk '/^samples  / {gsub(/[(),]/, ""); print $4}' "$out/${tag}_default.log")
scaled() { awk -v s="$spacing" -v f="$1" 'BEGIN { printf "%.5f", s * f }'; }

# kind|name|value|prt-precompute options|prt-relight render options
runs=(
    "budget|default|0|"
    "budget|Haar only, sh-terms 0|0|--sh-terms 0"
    "budget|coefficients 512|512|--coefficients 512"
    "budget|sample + node coefficients 1024|1024|--sample-coefficients 1024 --node-coefficients 1024"
    "budget|epsilon 0.01|0.01|--epsilon 0.01"
    "budget|cubemap 64|64|--cubemap-size 64"
    "budget|half spacing|$(scaled 0.5)|--sample-spacing $(scaled 0.5)"
    "budget|all truncations 1024|1024|--coefficients 1024 --sample-coefficients 1024 --node-coefficients 1024"
    "blocks|per vertex 128, no blocks|0|--block-coefficients 0"
    "blocks|blocks of 16 sharing 160|160|--block-coefficients 160"
    "blocks|blocks of 16 sharing 192|192|--block-coefficients 192"
    "coefficients|k 32|32|--coefficients 32"
    "coefficients|k 64|64|--coefficients 64"
    "coefficients|k 128|128|--coefficients 128"
    "coefficients|k 256|256|--coefficients 256"
    "coefficients|k 512|512|--coefficients 512"
    "density|spacing x2|$(scaled 2)|--sample-spacing $(scaled 2)"
    "density|spacing x1|$spacing|"
    "density|spacing x0.5|$(scaled 0.5)|--sample-spacing $(scaled 0.5)"
    "sun|sun split (k 2, cells of 8 degrees)|2||--sun-split"
    "sun|sun split k 8|8||--sun-split --sun-threshold 8"
    "sun|sun split k 32|32||--sun-split --sun-threshold 32"
    "sun|sun split, cells of 2 degrees|2||--sun-split --sun-cell 2"
    "sun|sun split, sh-terms 25|25|--sh-terms 25|--sun-split"
    "sun|sun split, half spacing|$(scaled 0.5)|--sample-spacing $(scaled 0.5)|--sun-split"
    "sun|sun split, all truncations 1024|1024|--coefficients 1024 --sample-coefficients 1024 --node-coefficients 1024|--sun-split"
)
declare -A made
for r in "${runs[@]}"; do
    IFS='|' read -r kind name value options render_options <<< "$r"
    read -r -a opts <<< "$options"
    read -r -a ropts <<< "$render_options"
    slug=$(echo "$name" | tr ' +.,' '____')
    # One transport file per set of precompute options (variants that differ only in
    # how they render share it).
    file=$out/${tag}_$(echo "$options" | tr -c 'a-zA-Z0-9\n' '_').prt
    if [[ -z $options ]]; then
        file=$out/${tag}_default.prt
        log=$out/${tag}_default.log
    else
        log=${file%.prt}.log
        if [[ $reuse == 1 && -f $file ]]; then
            echo "fidelity-budget: reusing $file (--reuse)"
        elif [[ -n ${made[$file]:-} ]]; then
            echo "fidelity-budget: $file made above for another variant (same options)"
        else
            precompute -o "$file" "${opts[@]}" > "$log"
            made[$file]=1
        fi
    fi
    seconds=$(awk '/^total/ { t = $2; if ($3 == "min") t = t * 60 + $4; print t }' "$log")
    for env in $envs; do
        img=$out/r_${tag}_${slug}_$env
        "$build/bin/prt-relight" render "$mesh" -t "$file" -e "$root/data/envmaps/$env.exr" \
            -W 256 -H 256 "${ropts[@]}" -o "$img" > /dev/null
        err=$("$build/bin/prt-compare" "$img.exr" "$out/ref_${tag}_$env.exr" | awk '/^overall/ {print $2}')
        printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\n' "$mat" "$kind" "$name" "$value" "$env" "$err" "$seconds" >> "$tsv"
        printf '%-10s %-13s %-36s %-7s rel RMSE %s  precompute %s s\n' "$mat" "$kind" "$name" "$env" "$err" "$seconds"
    done
done
echo "table: $tsv (plots: /usr/bin/python3 tools/plot_fidelity.py $tsv)"
