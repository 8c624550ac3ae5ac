#!/usr/bin/env bash
# The Slurm route end to end on this machine (docs/cluster.md): starts a private
# single-node Slurm (munged, slurmctld and slurmd on localhost, with a configuration,
# key, sockets, state and logs in a temporary directory; nothing system-wide is touched),
# submits pass 1, a job array of shards that load it and the dependent merge job through
# tools/slurm/submit.sh,
# waits, checks that the merged file equals the single-process file byte for byte, and
# shuts everything down (also on failure or Ctrl-C).
#
#   tools/test-slurm.sh [BUILD_DIR] [SHARDS]     (default build/, 4 shards)
#
# Needs Debian's slurmd, slurmctld, slurm-client and munge (tools/setup.sh --slurm) and
# root or sudo (slurmd runs jobs as their submitting user; munged must be allowed to
# run as this user). Exit 0 when the bytes match, 1 otherwise, 77 when Slurm is missing.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=$(cd "${1:-$root/build}" && pwd)
shards=${2:-4}
for tool in munged slurmctld slurmd sbatch squeue sacct; do
    command -v $tool > /dev/null || [ -x /usr/sbin/$tool ] || { echo "test-slurm: $tool not found (tools/setup.sh --slurm)"; exit 77; }
done
export PATH=$PATH:/usr/sbin
tmp=$(mktemp -d /tmp/prt-slurm.XXXXXX)
pids=()
cleanup() {
    for p in "${pids[@]}"; do kill "$p" 2> /dev/null || true; done
    sleep 1
    for p in "${pids[@]}"; do kill -9 "$p" 2> /dev/null || true; done
    if [ "${keep:-0}" = 1 ]; then echo "test-slurm: logs kept in $tmp"; else rm -rf "$tmp"; fi
}
trap cleanup EXIT
trap 'exit 1' INT TERM

# munge: its own key, socket and files.
mkdir -p "$tmp/munge" "$tmp/state" "$tmp/spool" "$tmp/work"
chmod 700 "$tmp/munge"
dd if=/dev/urandom of="$tmp/munge/munge.key" bs=1024 count=1 status=none
chmod 400 "$tmp/munge/munge.key"
munged --force --key-file="$tmp/munge/munge.key" --socket="$tmp/munge/munge.socket" \
    --pid-file="$tmp/munge/munged.pid" --log-file="$tmp/munge/munged.log" --seed-file="$tmp/munge/munged.seed"
pids+=("$(cat "$tmp/munge/munged.pid")")

# Free ports for slurmctld and slurmd.
port() {  # a port nothing listens on (bash's /dev/tcp connects when something does)
    local p
    while :; do
        p=$(( 20000 + (RANDOM * 32768 + RANDOM) % 40000 ))
        (exec 3<> /dev/tcp/127.0.0.1/$p) 2> /dev/null || { echo $p; return; }
    done
}
ctld_port=$(port) slurmd_port=$(port)
while [ "$slurmd_port" = "$ctld_port" ]; do slurmd_port=$(port); done
host=$(hostname -s)
cpus=$(nproc)
memory=$(( $(awk '/MemTotal/ {print $2}' /proc/meminfo) / 1024 / 2 ))
user=$(id -un)
export SLURM_CONF=$tmp/slurm.conf
cat > "$SLURM_CONF" <<CONF
ClusterName=prt-test
SlurmctldHost=$host(127.0.0.1)
SlurmUser=$user
SlurmdUser=root
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
AuthType=auth/munge
AuthInfo=socket=$tmp/munge/munge.socket
CredType=cred/munge
StateSaveLocation=$tmp/state
SlurmdSpoolDir=$tmp/spool
SlurmctldPidFile=$tmp/slurmctld.pid
SlurmdPidFile=$tmp/slurmd.pid
SlurmctldLogFile=$tmp/slurmctld.log
SlurmdLogFile=$tmp/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
SchedulerType=sched/builtin
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
MpiDefault=none
ReturnToService=2
SlurmdTimeout=60
InactiveLimit=0
MinJobAge=300
NodeName=$host NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$memory State=UNKNOWN
PartitionName=test Nodes=$host Default=YES MaxTime=INFINITE State=UP OverSubscribe=YES
CONF
slurmctld -D -i -f "$SLURM_CONF" > "$tmp/slurmctld.out" 2>&1 &
pids+=($!)
slurmd -D -f "$SLURM_CONF" -N "$host" > "$tmp/slurmd.out" 2>&1 &
pids+=($!)
for ((t = 0; t < 60; t++)); do
    state=$(sinfo -h -o %t 2> /dev/null | head -1 || true)
    case "$state" in idle*|mix*|alloc*) break ;; esac
    sleep 1
done
[ -n "${state:-}" ] && case "$state" in idle*|mix*|alloc*) true ;; *) false ;; esac || {
    keep=1; echo "test-slurm: the node did not come up (state '${state:-none}'); logs in $tmp"
    tail -5 "$tmp/slurmctld.log" "$tmp/slurmd.log" 2> /dev/null; exit 1; }
echo "test-slurm: single-node Slurm up ($host, $cpus CPUs, ports $ctld_port/$slurmd_port)"

# The job: a generated sphere, multiple + single scattering with a 2-term phase.
cd "$tmp/work"
"$build/bin/prt-make-shape" icosphere sphere.obj --subdivisions 3 --radius 10 > /dev/null
job=(--size-mm 20 -m Skin1 --components ms,ss --g 0.3 --phase-terms 2 --phase-map-size 8 --cubemap-size 16
     --samples 2000 --path-samples 8)
start=$(date +%s)
"$build/bin/prt-precompute" sphere.obj "${job[@]}" -q -o whole.prt > /dev/null
export PRT_BIN_DIR=$build/bin
submitted=$("$root/tools/slurm/submit.sh" "$shards" "$tmp/work/sliced.prt" "$tmp/work/sphere.obj" "${job[@]}" \
    -- --chdir="$tmp/work" --cpus-per-task=1)
echo "test-slurm: $submitted"
merge=$(echo "$submitted" | sed -n 's/.*merge = job \([0-9]*\).*/\1/p')
for ((t = 0; t < 300; t++)); do
    [ -n "$(squeue -h -j "$merge" 2> /dev/null)" ] || break
    sleep 1
done
if [ ! -f sliced.prt ]; then
    keep=1; echo "FAIL: the merge job wrote no sliced.prt; job logs:"; tail -n 3 "$tmp"/work/*.log; exit 1
fi
leftover=$(ls "$tmp"/work/sliced.shard* "$tmp"/work/sliced.pass1 2> /dev/null || true)
if cmp -s sliced.prt whole.prt && [ -z "$leftover" ]; then
    grep -q "loaded from" "$tmp"/work/prt-shard-*_0.log || { keep=1; echo "FAIL: shard 0 did not load pass 1"; exit 1; }
    echo "test-slurm: pass 1 + $shards array tasks + merge = one process, byte for byte ($(( $(date +%s) - start )) s)"
else
    keep=1; echo "FAIL: the merged file differs from one process's (or shards were left: $leftover)"; exit 1
fi
