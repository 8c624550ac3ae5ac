#!/usr/bin/env bash
# The precompute split over processes through the real executables (CTest
# precompute_cluster; docs/cluster.md).
#
#   cluster_test.sh BUILD_DIR WORKDIR
#
# One small job (a generated sphere, multiple + single scattering with a 2-term phase,
# so every component kind and the view maps are split) is computed in one process; then
#   - as 4 shards (--shard i/4) joined by prt-merge, as 3 shards loading one pass-1 file
#     (--pass1-file, written once by --pass1-only), and as 2 shards from a job file;
#   - under mpirun with 1, 2 and 4 ranks (--oversubscribe: this machine has 2 cores),
#     and a job file under 2 ranks, the 4 ranks computing each single-scattering site
#     once between them (as many sites as one process);
# and every output must equal the single-process file byte for byte (blocked, the
# default: shards are per vertex and prt-merge --mesh forms the blocks; and 2 shards of a
# per-vertex job, --block-coefficients 0, against that job in one process). Then failures: a
# rank that fails (PRT_MPI_FAIL fault injection) must stop the whole job with exit 1 and
# the failing rank named on one line of prt-precompute's, leaving no output; a missing
# or duplicated shard and a shard handed to the renderer are one-line errors.
# MPI is what the build says (CMake passes it): "on" runs the MPI cases and fails without
# mpirun; "off" (configured with -DPRT_MPI=OFF) skips them and says so; "missing" (MPI
# requested but not found at configure time) fails.
set -u
if [ $# -ne 3 ]; then echo "usage: $0 BUILD_DIR WORKDIR on|off|missing" >&2; exit 2; fi
BUILD=$1 WORK=$2 MPI=$3
PRE=$BUILD/bin/prt-precompute MERGE=$BUILD/bin/prt-merge
RELIGHT=$BUILD/bin/prt-relight
rm -rf "$WORK" && mkdir -p "$WORK" && cd "$WORK" || exit 1
"$BUILD/bin/prt-make-shape" icosphere sphere.obj --subdivisions 3 --radius 10 > /dev/null || exit 1
oiiotool --pattern constant:color=1,1,1 64x32 3 -d float -o sky.exr > /dev/null || exit 1
# CI runs as root; Open MPI refuses that unless told.
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
# Keep Open MPI off the network interfaces of a sandbox: shared memory on one host.
export OMPI_MCA_btl=self,vader OMPI_MCA_btl_vader_single_copy_mechanism=none

job=(sphere.obj --size-mm 20 -m Skin1 --components ms,ss --g 0.3 --phase-terms 2 --phase-map-size 8
     --cubemap-size 16 --samples 2000 --path-samples 8 -q)
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }
same() {  # same FILE WHAT [ONE_PROCESS_FILE]
    if cmp -s "$1" "${3:-whole.prt}"; then echo "ok: $2 = one process, byte for byte"; else fail "$2 differs from one process"; fi
}

"$PRE" "${job[@]}" -o whole.prt > whole.log || { cat whole.log; echo "FAIL: single-process run"; exit 1; }
"$PRE" "${job[@]}" --block-coefficients 0 -o vertexwise.prt > /dev/null || { echo "FAIL: single-process run per vertex"; exit 1; }
"$BUILD/bin/prt-relight" info whole.prt | grep -q "blocked: " || fail "the default single-process file is not blocked"

# Shards, in any order, joined.
for i in 3 1 0 2; do "$PRE" "${job[@]}" --shard $i/4 -o part$i.prt > /dev/null || fail "shard $i/4"; done
"$MERGE" -o merged.prt part2.prt part0.prt part3.prt part1.prt --mesh sphere.obj > merge.log || fail "prt-merge"
same merged.prt "4 shards merged"

# Pass 1 once into a pass-1 file, shards that load it.
"$PRE" "${job[@]}" --pass1-file job.pass1 --pass1-only > /dev/null || fail "--pass1-only"
for i in 0 1 2; do
    "$PRE" "${job[@]}" --pass1-file job.pass1 --shard $i/3 -o p1part$i.prt > p1part$i.log || fail "shard $i/3 with --pass1-file"
done
grep -q "loaded from job.pass1" p1part1.log || fail "shard 1/3 did not load pass 1: $(grep 'pass 1' p1part1.log)"
"$MERGE" -o p1merged.prt p1part0.prt p1part1.prt p1part2.prt --mesh sphere.obj > /dev/null || fail "prt-merge of the pass-1 shards"
same p1merged.prt "3 shards loading one pass-1 file, merged"

# A job file targets shards too.
cat > shards.json <<JSON
{"defaults": {"mesh": "sphere.obj", "size-mm": 20, "material": "Skin1", "components": "ms,ss", "g": 0.3,
              "phase-terms": 2, "phase-map-size": 8, "cubemap-size": 16, "samples": 2000, "path-samples": 8},
 "jobs": [{"shard": "0/2", "output": "job0.prt"}, {"shard": "1/2", "output": "job1.prt"}]}
JSON
"$PRE" --jobs shards.json -q > /dev/null || fail "job file of shards"
"$MERGE" -o jobmerged.prt job1.prt job0.prt --mesh sphere.obj > /dev/null || fail "prt-merge of the job file's shards"
same jobmerged.prt "job file of 2 shards merged"

# A per-vertex job's shards need no mesh to join.
for i in 0 1; do "$PRE" "${job[@]}" --block-coefficients 0 --shard $i/2 -o vpart$i.prt > /dev/null || fail "per-vertex shard $i/2"; done
"$MERGE" -o vmerged.prt vpart1.prt vpart0.prt > /dev/null || fail "prt-merge of per-vertex shards"
same vmerged.prt "2 shards of a per-vertex job merged" vertexwise.prt

# Errors: one line each, naming the problem.
one_line() {  # one_line PATTERN COMMAND...: exit 1 and exactly one stderr line matching PATTERN
    local pattern=$1; shift
    "$@" > /dev/null 2> err.txt; local code=$?
    if [ $code -ne 1 ] || [ "$(wc -l < err.txt)" -ne 1 ] || ! grep -qE "$pattern" err.txt; then
        fail "'$*' exited $code with: $(cat err.txt)"
    else
        echo "ok: $(cat err.txt)"
    fi
}
one_line "^prt-merge: error: shards: .*blocks of 160 .*--mesh" "$MERGE" -o bad.prt part0.prt part1.prt part2.prt part3.prt
one_line "^prt-merge: error: shards: shard 3/4 is missing" "$MERGE" -o bad.prt part0.prt part1.prt part2.prt
one_line "^prt-merge: error: part1.prt: shard 1/4 is given twice" "$MERGE" -o bad.prt part0.prt part1.prt part1.prt part2.prt part3.prt
one_line "^prt-relight: error: part1.prt: is shard 1/4 .*prt-merge" "$RELIGHT" render sphere.obj -t part1.prt -e sky.exr -o bad
one_line "^prt-precompute: error: --shard: " "$PRE" "${job[@]}" --shard 4/4 -o bad.prt
[ ! -e bad.prt ] || fail "a failed merge left bad.prt"

run_mpi=0
case "$MPI" in
    on) if command -v mpirun > /dev/null; then run_mpi=1
        else fail "prt-precompute was built with MPI but mpirun is not on PATH"; fi ;;
    off) echo "SKIPPED: the MPI cases (configured with -DPRT_MPI=OFF)" ;;
    missing) fail "MPI was requested (PRT_MPI=ON) but CMake did not find it: install libopenmpi-dev openmpi-bin (tools/setup.sh) or configure with -DPRT_MPI=OFF" ;;
    *) echo "usage: $0 BUILD_DIR WORKDIR on|off|missing" >&2; exit 2 ;;
esac
if [ "$run_mpi" = 1 ]; then
    mpi=(mpirun --oversubscribe)
    for np in 1 2 4; do
        "${mpi[@]}" -np $np "$PRE" "${job[@]}" -o mpi$np.prt > mpi$np.log 2>&1 || { cat mpi$np.log; fail "mpirun -np $np"; }
        same mpi$np.prt "mpirun -np $np"
    done
    grep -q "2 MPI ranks" mpi2.log || fail "the -np 2 summary does not name its ranks: $(head -1 mpi2.log)"
    # The ranks share the single-scattering sites: each is computed once, as in one process.
    sites() { grep -oE '^  sites +[0-9]+' "$1" | grep -oE '[0-9]+$'; }
    if [ -n "$(sites whole.log)" ] && [ "$(sites mpi4.log)" = "$(sites whole.log)" ]; then
        echo "ok: 4 ranks computed $(sites mpi4.log) single-scattering sites, as one process"
        grep -qE "^  sites .*shared between the ranks: [0-9.e+]+ MB" mpi4.log ||
            fail "the -np 4 summary does not report the sites' exchange: $(grep '^  sites' mpi4.log)"
    else
        fail "4 ranks computed '$(sites mpi4.log)' single-scattering sites, one process '$(sites whole.log)'"
    fi
    "${mpi[@]}" -np 2 "$PRE" "${job[@]}" --pass1-file job.pass1 -o mpip1.prt > /dev/null 2>&1 || fail "mpirun with --pass1-file"
    same mpip1.prt "mpirun -np 2 loading the pass-1 file"
    cat > mpijobs.json <<JSON
{"defaults": {"mesh": "sphere.obj", "size-mm": 20, "material": "Skin1", "components": "ms,ss", "g": 0.3,
              "phase-terms": 2, "phase-map-size": 8, "cubemap-size": 16, "samples": 2000, "path-samples": 8},
 "jobs": [{"output": "mpijob.prt"}]}
JSON
    "${mpi[@]}" -np 2 "$PRE" --jobs mpijobs.json -q > /dev/null 2>&1 || fail "job file under mpirun -np 2"
    same mpijob.prt "job file under mpirun -np 2"

    # A failing rank stops every rank; rank 0 says which and why, once.
    for stage in 1 3 5; do
        PRT_MPI_FAIL=1:$stage "${mpi[@]}" -np 2 "$PRE" "${job[@]}" -o failed.prt > /dev/null 2> err.txt
        code=$?
        n=$(grep -c "^prt-precompute: error: " err.txt)
        if [ $code -eq 0 ] || [ "$n" -ne 1 ] || ! grep -q "^prt-precompute: error: rank 1 of 2: PRT_MPI_FAIL: injected failure in stage $stage" err.txt; then
            fail "rank 1 failing in stage $stage: exit $code, $n error lines: $(cat err.txt)"
        else
            echo "ok: rank 1 failing in stage $stage stops the job: $(grep '^prt-precompute' err.txt)"
        fi
        [ ! -e failed.prt ] || { fail "a failed MPI job left failed.prt"; rm -f failed.prt; }
    done
fi

leftover=$(find . -name '*.tmp*' | head -3)
[ -z "$leftover" ] || fail "temporary files left: $leftover"
if [ $failures -gt 0 ]; then echo "$failures failures"; exit 1; fi
echo "cluster_test: all cases passed"
