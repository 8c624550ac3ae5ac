#!/usr/bin/env bash
# Submits a precompute as a Slurm job array of N shards plus a merge job that runs
# when every shard succeeded (docs/cluster.md):
#
#   tools/slurm/submit.sh N OUTPUT MESH [prt-precompute options...] [-- sbatch options...]
#
# e.g. tools/slurm/submit.sh 16 statue.prt statue.ply --size-mm 300 -m Marble --components ms,ss
#      -- --cpus-per-task=32 --partition=long
# Prints the two job ids. PRT_BIN_DIR (exported to the jobs) names the build's bin folder
# when the tools are not on PATH.
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
if [ $# -lt 3 ]; then sed -n '2,10p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//' >&2; exit 2; fi
n=$1 output=$2 mesh=$3
shift 3
case "$n" in ''|*[!0-9]*|0) echo "submit.sh: error: N must be a positive whole number, got '$n'" >&2; exit 2 ;; esac
args=() sbatch_args=()
while [ $# -gt 0 ]; do
    if [ "$1" = -- ]; then shift; sbatch_args=("$@"); break; fi
    args+=("$1"); shift
done
array=$(sbatch --parsable --array=0-$((n - 1)) "${sbatch_args[@]}" "$here/precompute.sbatch" "$output" "$mesh" "${args[@]}")
array=${array%%;*}
merge=$(sbatch --parsable --dependency=afterok:"$array" --kill-on-invalid-dep=yes "${sbatch_args[@]}" \
    "$here/merge.sbatch" "$output" "$n" "$mesh")
merge=${merge%%;*}
echo "submitted: shards = job array $array (0-$((n - 1))), merge = job $merge (after all shards succeed) -> $output"
