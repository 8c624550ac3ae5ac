#!/usr/bin/env bash
# tools/tsis-frames.sh -- the hybrid's goal figures of docs/point-lights.md ("Whole
# frames"): texture-space importance sampling on the README's frame (dragon_vrip_res4,
# 11,102 faces, 30 mm, Skin2, one point light behind it, 512 x 512) as a user runs it,
# `prt-pointlight --method tsis` at each configuration below, for
#   - the time per new light position of the whole CPU frame (irradiance map, shadow
#     maps, draws, sums, per-pixel shading), two ways, RUNS rounds each (default 5), the
#     configurations interleaved in each round so that they see the same machine,
#     median (min..max):
#       one frame as prt-pointlight computes it (the "per new light position" of its
#       `times:` line: a cold first frame in a new process), and
#       the steady state of prt-bench-tsis (the median over --repeat 11 new light
#       positions in one process, each frame whole: what a viewer's worker sees);
#   - the linear relative RMSE against the independent reference
#     (out/pointlight-measurements/tsis/reference.exr, made by
#     `tools/pointlight-measurements.sh tsis` when missing) at seeds 1 .. SEEDS (default
#     6): RMS and largest, and seed 1's.
# Configurations: the defaults; the defaults with every sample summed (--cluster-angle
# 0); the former defaults (atlas 1024, L = C = 20, N = 900, every sample); the former
# README options (atlas 512, L = C = 16, N = 1200, every sample).
# Usage: RUNS=5 SEEDS=6 tools/tsis-frames.sh
# Needs the fetched meshes (tools/fetch-data.sh) and a Release build in $BUILD_DIR
# (default build/). About 3 minutes on 2 cores (plus 1 for the reference). Output:
# out/tsis-frames/table.md and the logs beside it. The steal time of the run (vmstat's
# "st", a shared host's) is printed with the table: times taken under steal are slower.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${BUILD_DIR:-$root/build}
out=$root/out/tsis-frames
runs=${RUNS:-5}
seeds=${SEEDS:-6}
for tool in prt-pointlight prt-compare prt-reference; do
    [ -x "$build/bin/$tool" ] || { echo "tsis-frames: build first (tools/build.sh): $build/bin/$tool is missing" >&2; exit 1; }
done
mkdir -p "$out"
cd "$root"
reference=out/pointlight-measurements/tsis/reference.exr
[ -f "$reference" ] || BUILD_DIR=$build tools/pointlight-measurements.sh tsis
scene=(data/meshes/dragon_vrip_res4.ply.gz --size-mm 30 -m Skin2 --light point:-20,40,-60:0.04 -W 512 -H 512
       --method tsis)
labels=(defaults "every sample" "former defaults" "former README")
# Per configuration: prt-pointlight's options and prt-bench-tsis's (the same settings).
options=("" "--cluster-angle 0" "--atlas-size 1024 --rings 20 --ring-samples 20 --tsis-samples 900 --cluster-angle 0 --evaluate vertex"
         "--atlas-size 512 --rings 16 --ring-samples 16 --tsis-samples 1200 --cluster-angle 0 --evaluate vertex")
bench_options=("--samples 3600" "--samples 3600 --cluster-angle 0"
               "--atlas-size 1024 --rings 20 --ring-samples 20 --samples 900 --cluster-angle 0"
               "--atlas-size 512 --rings 16 --ring-samples 16 --samples 1200 --cluster-angle 0")

# frame LABEL_INDEX SEED: one run; prints the seconds per new light position.
frame() {
    local log=$out/config$1_seed$2.log
    # shellcheck disable=SC2086
    "$build/bin/prt-pointlight" "${scene[@]}" ${options[$1]} --tsis-seed "$2" -o "$out/config$1_seed$2" > "$log" 2>&1 ||
        { echo "tsis-frames: prt-pointlight failed, see $log" >&2; exit 1; }
    grep '^times:' "$log" | sed -E 's/.*= ([0-9.]+) s per new light position.*/\1/'
}
# steady LABEL_INDEX: one prt-bench-tsis run; prints its whole frame in seconds.
steady() {
    local log=$out/bench$1.log
    # shellcheck disable=SC2086
    "$build/bin/prt-bench-tsis" data/meshes/dragon_vrip_res4.ply.gz --size-mm 30 -m Skin2 --light point:-20,40,-60:0.04 \
        -W 512 -H 512 --split hybrid --repeat 11 ${bench_options[$1]} > "$log" 2>&1 ||
        { echo "tsis-frames: prt-bench-tsis failed, see $log" >&2; exit 1; }
    awk -F'|' '$2 ~ /^ *[0-9]+ *$/ { split($8, a, " "); print a[1] / 1000 }' "$log"
}
stats() {
    python3 -c "import statistics, sys; v = [1e3 * float(x) for x in sys.argv[1:]]; m = statistics.median(v); print('%.1f ms (%.1f..%.1f) | %.1f' % (m, min(v), max(v), 1e3 / m))" "$@"
}

vmstat 1 > "$out/vmstat.log" &
vmstat_pid=$!
trap 'kill $vmstat_pid 2> /dev/null || true' EXIT
declare -a times steadies
for ((round = 1; round <= runs; round++)); do
    echo "== round $round of $runs" >&2
    for i in "${!labels[@]}"; do
        times[$i]="${times[$i]:-} $(frame "$i" 1)"
        steadies[$i]="${steadies[$i]:-} $(steady "$i")"
    done
done
kill $vmstat_pid 2> /dev/null || true
steal=$(awk 'NR > 2 { s += $17; n++ } END { if (n) printf "%.0f", s / n; else print "?" }' "$out/vmstat.log")

{
    echo "# tsis-frames: prt-pointlight ${scene[*]} [OPTIONS], $runs rounds, seeds 1..$seeds"
    echo
    echo "Mean steal time over the rounds: $steal% (vmstat st)."
    echo
    echo "| configuration | options | one frame (prt-pointlight), median (min..max) | per second | steady state (prt-bench-tsis) | per second | error vs reference, seed 1 | RMS over seeds (largest) |"
    echo "|---|---|---|---|---|---|---|---|"
    for i in "${!labels[@]}"; do
        errors=()
        for ((seed = 1; seed <= seeds; seed++)); do
            [ "$seed" = 1 ] || frame "$i" "$seed" > /dev/null
            errors+=("$("$build/bin/prt-compare" "$out/config${i}_seed$seed.exr" "$reference" | awk '$1 == "overall" { print $2 }')")
        done
        err=$(python3 -c "import math, sys; v = [float(x) for x in sys.argv[1:]]; print('%.2f%% | %.2f%% (%.2f%%)' % (100 * v[0], 100 * math.sqrt(sum(x * x for x in v) / len(v)), 100 * max(v)))" "${errors[@]}")
        # shellcheck disable=SC2086
        echo "| ${labels[$i]} | \`${options[$i]:-}\` | $(stats ${times[$i]}) | $(stats ${steadies[$i]}) | $err |"
    done
} | tee "$out/table.md"
