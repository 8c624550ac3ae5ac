#!/usr/bin/env bash
# The test suite under AddressSanitizer + UndefinedBehaviorSanitizer (docs/reliability.md):
# a RelWithDebInfo build with PRT_SANITIZE=ON in build-asan/ (BUILD_DIR to change),
# then every test except the viewer's (Mesa's llvmpipe is not instrumented and
# reports its own leaks). Extra arguments go to ctest (e.g. -R Transport).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build_dir=${BUILD_DIR:-$root/build-asan}
"$root/tools/setup.sh"
cmake -S "$root" -B "$build_dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPRT_SANITIZE=ON >/dev/null
cmake --build "$build_dir" -j"${JOBS:-$(nproc)}"
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1:strict_string_checks=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
cd "$build_dir"
ctest --output-on-failure -j"${JOBS:-$(nproc)}" -LE viewer "$@"
