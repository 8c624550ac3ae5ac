#!/usr/bin/env bash
# tools/cache-measurements.sh -- the irradiance cache's goal figures of docs/point-lights.md
# ("The cache's goals"): for each Keng-table scene, RUNS paired runs (default 5) of
# `prt-pointlight --method cache --compare-jb` at the defaults, each timing the cache
# (T_cache) and Jensen-Buhler (T_JB) on the same samples, octree and G-buffer in one
# process, so the speedup of a run is a ratio measured in the same run. Reports the
# median with min..max of T_cache, T_JB and the speedup, the caches' share of the hit
# pixels, and the cache frame's linear relative RMSE against the independent reference
# (out/pointlight-measurements/<scene>/reference.exr from tools/pointlight-measurements.sh,
# when it is there) and against Jensen-Buhler.
# Usage: tools/cache-measurements.sh [scene ...]   scenes: dragon bunny armadillo (default all)
#        RUNS=5 EXTRA="--a 0.01" tools/cache-measurements.sh ...   (EXTRA: options added to every run)
# Needs the fetched meshes (tools/fetch-data.sh) and a Release build in $BUILD_DIR
# (default build/). About 5 minutes on 2 cores at RUNS=5; time it on a quiet machine.
# Output: out/cache-measurements/<scene>.md and the logs beside them.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${BUILD_DIR:-$root/build}
out=$root/out/cache-measurements
runs=${RUNS:-5}
for tool in prt-pointlight prt-compare; do
    [ -x "$build/bin/$tool" ] || { echo "cache-measurements: build first (tools/build.sh): $build/bin/$tool is missing" >&2; exit 1; }
done
mkdir -p "$out"
cd "$root"
m=data/meshes

# stats V...: "median (min..max)" of the numbers.
stats() {
    python3 -c "import statistics, sys; v = [float(x) for x in sys.argv[1:]]; print('%.3g (%.3g..%.3g)' % (statistics.median(v), min(v), max(v)))" "$@"
}

scene() {
    local name=$1
    shift
    local dir=$out/$name
    mkdir -p "$dir"
    local tc=() tj=() sp=()
    local k
    for ((k = 1; k <= runs; ++k)); do
        echo "== $name: run $k of $runs" >&2
        # shellcheck disable=SC2086
        "$build/bin/prt-pointlight" "$@" --method cache --compare-jb ${EXTRA:-} -o "$dir/cache" > "$dir/run$k.log" 2>&1
        tc+=("$(grep -oE 'T_cache [0-9.]+ s$' "$dir/run$k.log" | grep -oE '[0-9.]+')")
        tj+=("$(grep -oE 'T_JB [0-9.]+ s' "$dir/run$k.log" | grep -oE '[0-9.]+')")
        sp+=("$(grep -oE 'speedup [0-9.]+x' "$dir/run$k.log" | grep -oE '[0-9.]+')")
    done
    local log=$dir/run$runs.log
    local caches vsjb vsref="(no reference: run tools/pointlight-measurements.sh $name)"
    caches=$(grep -oE '[0-9]+ caches / [0-9]+ hit pixels = [0-9.]+%' "$log" | head -1)
    vsjb=$(grep -oE 'relative RMSE \(linear\) [0-9.e-]+' "$log" | grep -oE '[0-9.e-]+$')
    local ref=$root/out/pointlight-measurements/$name/reference.exr
    if [ -f "$ref" ]; then
        vsref=$("$build/bin/prt-compare" "$dir/cache.exr" "$ref" | awk '$1 == "overall" { printf "%.2f%% (mean ratio %.4f)", 100 * $2, $NF }')
    fi
    {
        echo "# $name: prt-pointlight $* --method cache --compare-jb ${EXTRA:-}"
        echo
        echo "| caches | cache vs reference | cache vs JB | T_cache, s | T_JB, s | speedup (same run) |"
        echo "|---|---|---|---|---|---|"
        echo "| $caches | $vsref | $(python3 -c "print('%.2f%%' % (100 * float('$vsjb')))") | $(stats "${tc[@]}") | $(stats "${tj[@]}") | $(stats "${sp[@]}")x |"
        echo
        grep -E '^near field' "$log" | sed 's/^/    /'
        echo "($runs paired runs: median (min..max); $(nproc) cores)"
    } > "$out/$name.md"
    cat "$out/$name.md"
}

scenes=("$@")
[ ${#scenes[@]} -gt 0 ] || scenes=(dragon bunny armadillo)
for s in "${scenes[@]}"; do
    case $s in
        dragon) scene dragon "$m/dragon_vrip_res2.ply.gz" --size-mm 40 -m Skimmilk --light point:30,40,20:0.01 \
                    -W 1024 -H 1024 --exposure -1 ;;
        bunny) scene bunny "$m/bunny.off" --size-mm 40 -m Marble --light point:30,40,30:0.01 \
                   -W 1024 -H 1024 --exposure -1 ;;
        armadillo) scene armadillo "$m/armadillo.off" --size-mm 40 -m Skin1 --azimuth 180 \
                       --light point:30,40,-30:0.01 -W 1024 -H 1024 --exposure -1 ;;
        *) echo "cache-measurements: unknown scene '$s' (dragon, bunny, armadillo)" >&2; exit 1 ;;
    esac
done
