#!/usr/bin/env bash
# The test suite under the sanitizers (docs/reliability.md).
#
#   tools/sanitize.sh [ctest arguments]   ASan + UBSan: RelWithDebInfo, PRT_SANITIZE=ON in
#                                         build-asan/, every test except the viewer's (Mesa's
#                                         llvmpipe is not instrumented and reports its own leaks)
#   tools/sanitize.sh --thread            ThreadSanitizer: PRT_TSAN=ON in build-tsan/, the test
#                                         programs of the threaded passes on their small inputs
#
# BUILD_DIR overrides the build directory, JOBS the parallelism.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
"$root/tools/setup.sh"

if [ "${1:-}" != "--thread" ]; then
  build_dir=${BUILD_DIR:-$root/build-asan}
  cmake -S "$root" -B "$build_dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPRT_SANITIZE=ON >/dev/null
  cmake --build "$build_dir" -j"${JOBS:-$(nproc)}"
  export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1:strict_string_checks=1}
  export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
  # OpenImageIO's PNG error-string leak (the fuzzers' suppression file says why).
  export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$root/tools/fuzz/lsan.supp:print_suppressions=0}
  cd "$build_dir"
  exec ctest --output-on-failure -j"${JOBS:-$(nproc)}" -LE viewer "$@"
fi

# ThreadSanitizer. Every parallel pass runs on oneTBB (parallel_for, task_group), and
# Embree builds its BVH on it too. Debian's libtbb is not instrumented, so TSan cannot see
# its synchronisation and reports every hand-over between TBB threads as a race (tried:
# 12 of 14 programs "failed" that way). The script therefore builds the same oneTBB
# version from Debian's source package with TBB_SANITIZE=thread (~30 s, once, into
# build-tsan/onetbb/) and links the tests against it; Embree, which loads libtbb.so.12
# by soname, then runs on the instrumented one as well.
shift
build_dir=${BUILD_DIR:-$root/build-tsan}
tbb_prefix=$build_dir/onetbb
if [ ! -f "$tbb_prefix/lib/cmake/TBB/TBBConfig.cmake" ]; then
  package=$(dpkg-query -W -f='${source:Package}' libtbb-dev)
  version=$(dpkg-query -W -f='${source:Version}' libtbb-dev)
  src=$build_dir/onetbb-src
  rm -rf "$src"
  mkdir -p "$src/apt/lists/partial" "$src/apt/cache/archives/partial" "$src/apt/parts"
  # deb-src entries for the machine's own Debian sources (its apt configuration names them).
  for f in /etc/apt/sources.list.d/*.sources; do
    [ -f "$f" ] && { sed 's/^Types: deb$/Types: deb-src/' "$f"; echo; }
  done > "$src/apt/parts/source.sources"
  grep -hs '^deb ' /etc/apt/sources.list | sed 's/^deb /deb-src /' > "$src/apt/source.list" || true
  apt_options=(-o Dir::Etc::SourceList="$src/apt/source.list" -o Dir::Etc::SourceParts="$src/apt/parts"
               -o Dir::State::Lists="$src/apt/lists" -o Dir::Cache="$src/apt/cache" -o APT::Sandbox::User=root)
  apt-get -qq "${apt_options[@]}" update
  (cd "$src" && apt-get -qq "${apt_options[@]}" source --download-only "$package=$version")
  tar -C "$src" -xf "$src"/"${package}"_*.orig.tar.*
  tbb_source=$(find "$src" -maxdepth 1 -mindepth 1 -type d ! -name apt | head -1)
  cmake -S "$tbb_source" -B "$src/build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DTBB_TEST=OFF -DTBB_STRICT=OFF \
    -DTBBMALLOC_BUILD=OFF -DTBB_SANITIZE=thread -DCMAKE_INSTALL_PREFIX="$tbb_prefix" >/dev/null
  cmake --build "$src/build" -j"${JOBS:-$(nproc)}" >/dev/null
  cmake --install "$src/build" >/dev/null
  echo "sanitize.sh: built $package $version with ThreadSanitizer into $tbb_prefix"
fi

tests=(core atomic_file multiple_scattering irradiance_transport pipeline single_scattering relight_kernel render
       reference point_lights jensen_buhler irradiance_cache surface_atlas texture_space_sampling distribution)
cmake -S "$root" -B "$build_dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPRT_TSAN=ON -DPRT_BUILD_VIEWER=OFF \
  -DTBB_DIR="$tbb_prefix/lib/cmake/TBB" >/dev/null
cmake --build "$build_dir" -j"${JOBS:-$(nproc)}" --target "${tests[@]/#/test_}"
export TSAN_OPTIONS=${TSAN_OPTIONS:-halt_on_error=0:second_deadlock_stack=1:suppressions=$root/tools/tsan.supp}
failed=()
for t in "${tests[@]}"; do
  echo "== test_$t"
  # TSan exits 66 after the tests when it reported anything.
  if ! (cd "$build_dir/tests" && ./test_"$t" --gtest_brief=1 "$@"); then failed+=("$t"); fi
done
echo "ThreadSanitizer: ${#tests[@]} test programs, ${#failed[@]} failed${failed:+: ${failed[*]}}"
[ ${#failed[@]} -eq 0 ]
