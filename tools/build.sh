#!/usr/bin/env bash
# Configures and builds the project into build/ (Release unless BUILD_TYPE is set):
# everything, or only the targets named (tools/build.sh prt-precompute prt-relight).
# A new build directory uses Ninja when it is installed (tools/setup.sh installs it; it
# keeps both cores busy across the libraries' boundaries, where make waits); an
# existing one keeps the generator it was made with.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build_dir=${BUILD_DIR:-$root/build}
jobs=${JOBS:-$(nproc)}
generator=()
if [ ! -f "$build_dir/CMakeCache.txt" ] && command -v ninja >/dev/null 2>&1; then
  generator=(-G Ninja)
fi
cmake -S "$root" -B "$build_dir" "${generator[@]}" -DCMAKE_BUILD_TYPE="${BUILD_TYPE:-Release}" >/dev/null
targets=()
for t in "$@"; do targets+=(--target "$t"); done
cmake --build "$build_dir" -j"$jobs" "${targets[@]}"
