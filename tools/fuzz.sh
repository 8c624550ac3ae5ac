#!/usr/bin/env bash
# Runs every libFuzzer target of tools/fuzz/ (docs/reliability.md, "Fuzzing").
#
#   tools/fuzz.sh [SECONDS] [TARGET...]
#
# SECONDS of fuzzing per target (default 60; 600 = the 10 CPU-minutes each target
# needs before a hardening change is resolved), all targets when none is named:
# transport_file mesh environment job_file light_scene command_line. Builds
# build-fuzz/ with clang (-fsanitize=fuzzer,address,undefined; BUILD_DIR to change),
# installs clang through tools/setup.sh --fuzz, runs JOBS targets at a time (default:
# the number of cores), each in an empty working directory, one process per target.
#
# Each target starts from the committed seeds (tools/fuzz/corpus/<target>/) and the
# corpus earlier runs grew (build-fuzz/fuzz/corpus/<target>/, not committed). A crash,
# sanitizer report, leak, timeout (> 10 s per input) or memory blow-up (> 2.5 GB) is
# saved as build-fuzz/fuzz/crashes/<target>/<kind>-<sha1>; commit each such input, once
# fixed, to tools/fuzz/crashes/<target>/ so CTest fuzz_replay_<target> keeps it fixed.
# Ends with a table per target: CPU seconds (user + system), runs, coverage, corpus
# size, findings; exit 1 when anything was found.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build_dir=${BUILD_DIR:-$root/build-fuzz}
all_targets=(transport_file mesh environment job_file light_scene command_line)

seconds=60
if [ $# -gt 0 ]; then
  case "$1" in
    -h|--help) sed -n '2,19p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; exit 0 ;;
    ''|*[!0-9]*) echo "fuzz.sh: error: SECONDS must be a whole number, got '$1' (see --help)" >&2; exit 1 ;;
    *) seconds=$1; shift ;;
  esac
fi
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=("${all_targets[@]}")
for t in "${targets[@]}"; do
  [ -d "$root/tools/fuzz/corpus/$t" ] || { echo "fuzz.sh: error: unknown target '$t' (valid: ${all_targets[*]})" >&2; exit 1; }
done

"$root/tools/setup.sh" --fuzz
CC=clang CXX=clang++ cmake -S "$root" -B "$build_dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPRT_FUZZ=ON \
  -DPRT_BUILD_TESTS=OFF -DPRT_BUILD_VIEWER=OFF >/dev/null
cmake --build "$build_dir" -j"$(nproc)" --target fuzz-all

work=$build_dir/fuzz
mkdir -p "$work/logs"
# The targets write each input to a file (and the transport-file target saves it back,
# with an fsync): on disk a target spent 95% of its time waiting for the disk (30 CPU
# seconds in 650 s); in memory it runs on the CPU.
if [ -z "${TMPDIR:-}" ] && [ -d /dev/shm ] && [ -w /dev/shm ]; then export TMPDIR=/dev/shm; fi
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:allocator_may_return_null=0}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$root/tools/fuzz/lsan.supp:print_suppressions=0}
# Readable stack traces (Debian names the symbolizer with its version).
[ -n "${ASAN_SYMBOLIZER_PATH:-}" ] || ! command -v llvm-symbolizer-14 >/dev/null || export ASAN_SYMBOLIZER_PATH=$(command -v llvm-symbolizer-14)

run_target() {
  local t=$1 seconds=$2 build_dir=$3 root=$4
  local work=$build_dir/fuzz
  mkdir -p "$work/corpus/$t" "$work/crashes/$t" "$work/cwd/$t"
  # An empty working directory: the command-line target must find no file to load.
  find "$work/cwd/$t" -mindepth 1 -delete
  cd "$work/cwd/$t"
  local status=0
  local TIMEFORMAT='%U %S'
  local leaks=1
  # OpenImageIO leaks an error string on every corrupt PNG (tools/fuzz/lsan.supp); with
  # leak detection on, libFuzzer re-checks each such input with LeakSanitizer and the
  # target slows from ~100 to ~5 runs/s. Our code's leaks are the ASan test run's job.
  [ "$t" != environment ] || leaks=0
  # The transport-file target also starts from the golden files of tests/golden/.
  local seeds=("$work/corpus/$t" "$root/tools/fuzz/corpus/$t")
  [ "$t" != transport_file ] || seeds+=("$root/tests/golden")
  { time "$build_dir/bin/fuzz-$t" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2560 -detect_leaks=$leaks \
      -malloc_limit_mb=2560 -close_fd_mask=3 -print_final_stats=1 -max_len=65536 \
      -artifact_prefix="$work/crashes/$t/" "${seeds[@]}" \
      >"$work/logs/$t.log" 2>&1 || status=$?; } 2>"$work/logs/$t.cpu"
  echo "$status" >"$work/logs/$t.status"
}
export -f run_target

echo "fuzz.sh: ${#targets[@]} targets x ${seconds} s, ${JOBS:-$(nproc)} at a time; logs in $work/logs/"
start=$(date +%s)
printf '%s\n' "${targets[@]}" |
  xargs -P "${JOBS:-$(nproc)}" -I{} bash -c 'run_target "$@"' _ {} "$seconds" "$build_dir" "$root" || true
echo "fuzz.sh: done in $(( $(date +%s) - start )) s"

found=0
printf '\n| target | CPU seconds | runs | coverage (edges) | corpus | findings |\n|---|---|---|---|---|---|\n'
for t in "${targets[@]}"; do
  log=$work/logs/$t.log
  runs=$(grep -o 'stat::number_of_executed_units: [0-9]*' "$log" | awk '{print $2}' | tail -1)
  secs=$(awk '{printf "%.0f", $1 + $2}' "$work/logs/$t.cpu" 2>/dev/null)
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | awk '{print $2}')
  corpus=$(find "$work/corpus/$t" -type f | wc -l)
  findings=$(find "$work/crashes/$t" -type f | wc -l)
  status=$(cat "$work/logs/$t.status" 2>/dev/null || echo "?")
  [ "$status" = 0 ] || [ "$findings" -gt 0 ] || findings="exit $status"
  [ "$findings" = 0 ] || found=1
  printf '| %s | %s | %s | %s | %s | %s |\n' "$t" "${secs:-?}" "${runs:-?}" "${cov:-?}" "$corpus" "$findings"
done
if [ "$found" = 1 ]; then
  echo "fuzz.sh: findings in $work/crashes/ (reproduce: $build_dir/bin/fuzz-<target> <input>)" >&2
  exit 1
fi
