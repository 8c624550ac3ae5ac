#!/usr/bin/env bash
# The measurements of docs/cluster.md on this machine: one precompute (default mesh
# data/meshes/dragon_vrip_res4.ply.gz, 30 mm, Marble, multiple + isotropic single
# scattering) run
#   1. in one process with T threads (T = the machine's cores),
#   2. under mpirun with R ranks of T/R threads each (the same cores),
#   3. as R shards one after the other with T threads each, then prt-merge,
# with the wall times, each rank's busy time, the exchange, and a cmp of every file
# against the first. Usage:
#
#   tools/cluster-measurements.sh [MESH] [RANKS] [extra prt-precompute options]
#
# Outputs and JSON summaries in out/cluster/.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
mesh=${1:-$root/data/meshes/dragon_vrip_res4.ply.gz}
ranks=${2:-2}
shift $(( $# > 2 ? 2 : $# )) || true
extra=("$@")
B=$root/build
out=$root/out/cluster
mkdir -p "$out"
cores=$(nproc)
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
export OMPI_MCA_btl=self,vader OMPI_MCA_btl_vader_single_copy_mechanism=none
job=("$mesh" --size-mm 30 -m Marble --components ms,ss -q -f "${extra[@]}")
now() { date +%s.%N; }
field() { python3 -c "import json,sys; d=json.load(open(sys.argv[1])); print(d$2)" "$1"; }

t0=$(now)
"$B/bin/prt-precompute" "${job[@]}" -j "$cores" -o "$out/one.prt" --summary-json "$out/one.json" > /dev/null
t1=$(now)
mpirun --oversubscribe -np "$ranks" "$B/bin/prt-precompute" "${job[@]}" -j $(( cores / ranks > 0 ? cores / ranks : 1 )) \
    -o "$out/mpi.prt" --summary-json "$out/mpi.json" > /dev/null
t2=$(now)
shards=()
for ((i = 0; i < ranks; i++)); do
    "$B/bin/prt-precompute" "${job[@]}" -j "$cores" --shard "$i/$ranks" -o "$out/shard$i.prt" \
        --summary-json "$out/shard$i.json" > /dev/null
    shards+=("$out/shard$i.prt")
done
t3=$(now)
"$B/bin/prt-merge" -o "$out/merged.prt" "${shards[@]}" > /dev/null
t4=$(now)

same() { cmp -s "$1" "$out/one.prt" && echo "identical" || echo "DIFFERENT"; }
s() { python3 -c "print(f'{$1:.1f}')"; }
echo "| run | wall s | pass 1 s | pass 2 s | single scattering s | busy per rank s | file vs one process |"
echo "|---|---|---|---|---|---|---|"
echo "| 1 process, $cores threads | $(s "$t1 - $t0") | $(s "$(field "$out/one.json" "['summary']['pass1_seconds']")") | $(s "$(field "$out/one.json" "['summary']['pass2_seconds']")") | $(s "$(field "$out/one.json" "['summary']['ss_seconds']")") | | reference |"
echo "| mpirun -np $ranks, $(( cores / ranks > 0 ? cores / ranks : 1 )) threads each | $(s "$t2 - $t1") | $(s "$(field "$out/mpi.json" "['summary']['pass1_seconds']")") | $(s "$(field "$out/mpi.json" "['summary']['pass2_seconds']")") | $(s "$(field "$out/mpi.json" "['summary']['ss_seconds']")") | $(s "$(field "$out/mpi.json" "['summary']['busy_seconds_min']")")-$(s "$(field "$out/mpi.json" "['summary']['busy_seconds_max']")") | $(same "$out/mpi.prt") |"
echo "| $ranks shards in turn, $cores threads, + prt-merge | $(s "$t3 - $t2") + $(s "$t4 - $t3") | | | | | $(same "$out/merged.prt") |"
for ((i = 0; i < ranks; i++)); do
    j=$out/shard$i.json
    echo "|   shard $i/$ranks | $(s "$(field "$j" "['summary']['total_seconds']")") | $(s "$(field "$j" "['summary']['pass1_seconds']")") | $(s "$(field "$j" "['summary']['pass2_seconds']")") | $(s "$(field "$j" "['summary']['ss_seconds']")") | | |"
done
echo
echo "samples $(field "$out/one.json" "['summary']['samples']"), vertices $(field "$out/one.json" "['summary']['vertices']"), file $(field "$out/one.json" "['summary']['file_bytes']") bytes;" \
     "MPI exchange $(field "$out/mpi.json" "['summary']['pass1_exchange_bytes']") bytes in $(field "$out/mpi.json" "['summary']['pass1_exchange_seconds']") s, gather $(field "$out/mpi.json" "['summary']['gather_seconds']") s"
