#!/usr/bin/env bash
# Sets up a fresh machine, builds everything and runs every test (no network needed
# beyond the Debian packages that tools/setup.sh installs).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build_dir=${BUILD_DIR:-$root/build}
start=$(date +%s)
"$root/tools/setup.sh" --slurm
"$root/tools/build.sh"
cd "$build_dir"
ctest --output-on-failure -j"$(nproc)" "$@"
echo "test.sh: all tests done in $(( $(date +%s) - start )) s"
