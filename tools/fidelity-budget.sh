#!/usr/bin/env bash
# The error budget of docs/fidelity.md: the bunny (30 mm) precomputed with the defaults
# and with one approximation relaxed at a time, rendered at 256 x 256 under forest and
# city, each compared with prt-reference's independent render (made once per
# environment, a few minutes each). Prints one line per variant and environment.
#   tools/fidelity-budget.sh [MATERIAL] [OUT_DIR]      (defaults: Marble, out/budget)
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
bin=${BUILD_DIR:-$root/build}
mat=${1:-Marble}
out=${2:-$root/out/budget}
mesh=$root/data/meshes/bunny.off
mkdir -p "$out"
precompute() { "$bin/precompute/prt-precompute" "$mesh" --size-mm 30 --material "$mat" --force "$@"; }

precompute -o "$out/${mat}_default.prt" > "$out/${mat}_default.log"
for env in forest city; do
    ref=$out/ref_${mat}_$env
    [[ -f $ref.exr ]] || "$bin/tools/prt-reference" "$mesh" -t "$out/${mat}_default.prt" \
        -e "$root/data/envmaps/$env.exr" -W 256 -H 256 -o "$ref" > "$ref.log"
done

spacing=$(awk '/^samples  / {gsub(/[(),]/, ""); print $4}' "$out/${mat}_default.log")
half=$(awk -v s="$spacing" 'BEGIN { printf "%.5f", s / 2 }')
variants=(
    "default|"
    "k512|--coefficients 512"
    "sample1024|--sample-coefficients 1024 --node-coefficients 1024"
    "eps001|--epsilon 0.01"
    "cube64|--cubemap-size 64"
    "spacing_half|--sample-spacing $half"
    "all1024|--coefficients 1024 --sample-coefficients 1024 --node-coefficients 1024"
)
for v in "${variants[@]}"; do
    name=${v%%|*}
    read -r -a opts <<< "${v#*|}"
    file=$out/${mat}_$name.prt
    [[ $name == default ]] || precompute -o "$file" "${opts[@]}" > "$out/${mat}_$name.log"
    total=$(awk '/^total/ {print $2, $3}' "$out/${mat}_$name.log")
    for env in forest city; do
        "$bin/relight/prt-relight" render "$mesh" -t "$file" -e "$root/data/envmaps/$env.exr" \
            -W 256 -H 256 -o "$out/r_${mat}_${name}_$env" > /dev/null
        err=$("$bin/tools/prt-compare" "$out/r_${mat}_${name}_$env.exr" "$out/ref_${mat}_$env.exr" |
              awk '/^overall/ {print $2}')
        printf '%-8s %-14s %-7s rel RMSE %s  precompute %s\n' "$mat" "$name" "$env" "$err" "$total"
    done
done
