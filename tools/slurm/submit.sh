#!/usr/bin/env bash
# Submits a precompute as a Slurm job: pass 1 once (tools/slurm/pass1.sbatch, into
# OUTPUT's name with .pass1; skipped for --components ss), then a job array of N shards
# that load it, then a merge job once every shard succeeded (docs/cluster.md):
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
# Single scattering alone has no pass 1.
pass1_job=() after_pass1=()
if ! printf '%s\n' "${args[@]}" | paste -sd' ' | grep -qE -- '--components[= ]ss( |$)'; then
    pass1=${output%.prt}.pass1
    p1=$(sbatch --parsable "${sbatch_args[@]}" "$here/pass1.sbatch" "$pass1" "$mesh" "${args[@]}")
    p1=${p1%%;*}
    pass1_job=("pass 1 = job $p1,")
    after_pass1=(--dependency=afterok:"$p1" --kill-on-invalid-dep=yes)
    args+=(--pass1-file "$pass1")
fi
array=$(sbatch --parsable --array=0-$((n - 1)) "${after_pass1[@]}" "${sbatch_args[@]}" "$here/precompute.sbatch" \
    "$output" "$mesh" "${args[@]}")
array=${array%%;*}
merge=$(sbatch --parsable --dependency=afterok:"$array" --kill-on-invalid-dep=yes "${sbatch_args[@]}" \
    "$here/merge.sbatch" "$output" "$n" "$mesh")
merge=${merge%%;*}
echo "submitted: ${pass1_job[*]:+${pass1_job[*]} }shards = job array $array (0-$((n - 1))), merge = job $merge (after all shards succeed) -> $output"
