#!/usr/bin/env bash
# tools/bench.sh -- the benchmarks of SPEC section 8 in one run (docs/tools.md):
#   1. bench_relight: relight time per frame / time to stream its bytes at the measured
#      memory bandwidth, diffuse only and 1 diffuse + K = 4 terms (100,000 vertices x
#      128 coefficients), interleaved with 1 GiB sums; transport-file load time;
#   2. prt-bench-pass1: pass-1 occlusion rays/s / raw Embree rays/s (dragon res3);
#   3. prt-precompute: multiple + isotropic single scattering of dragon res4 with
#      --summary-json (pass 2 and single-scattering time per vertex, kd-tree nodes
#      visited per vertex, peak memory after each pass, file size per vertex);
#   4. prt-bench-relight-file: light vector and relight time per frame of that file, and
#      of the same job with --fold-ss (single scattering folded into one vector);
#   5. prt-bench-tsis: point lights by texture-space importance sampling (Chang et al.
#      2008's goal row: dragon res4, hybrid at its defaults, 512 x 512, per vertex as the
#      viewer): the time per new light position split into its stages, and a material
#      change (setMaterial) with the sums after it;
#   6. prt-pointlight --method cache --compare-jb: a point light by the translucent
#      irradiance cache (Keng et al. 2006) at its defaults on the bunny (1024 x 1024),
#      its time T_cache and Jensen-Buhler's T_JB on the same samples and octree in the
#      same run, their ratio, and the cache's distance from Jensen-Buhler;
#   7. prt-bench-edit: a material edit with the light still on the bunny's editable
#      file, and a light change on it against a plain per-vertex file; the same light
#      change on a blocked editable file (nested lists, 216 per block) against the
#      default blocked file, with the two files' sizes.
# Prints one Markdown table (with the command of each row) and writes it to
# out/bench/summary.md; raw outputs are kept in out/bench/*.log and *.json. With
# --repeat N the benchmarks that run once per process (2, 3, 4 and 6) run N times
# (NAME.rK.log / .json for K > 1) and the table shows their medians with (min..max);
# 1, 5 and 7 repeat inside their own process and report their own medians.
set -euo pipefail

usage() {
  cat <<'EOF'
Usage: tools/bench.sh [--no-build] [--repeat N] [--out DIR]

Builds (Release, into $BUILD_DIR, default build/) the benchmark tools, runs every
benchmark of SPEC section 8 and prints one Markdown table of the results, also
written to DIR/summary.md (DIR default out/bench); docs/tools.md gives how long it
takes. Needs the fetched data (tools/fetch-data.sh) and python3.

  --no-build   use the binaries already in $BUILD_DIR
  --repeat N   run pass 1, the precomputes, the file relights and the cache N times
               (default 1); the table shows each figure's median and (min..max).
               bench_relight, prt-bench-tsis and prt-bench-edit repeat inside one
               run already.
  --out DIR    where logs, JSON and summary.md go (default out/bench)
EOF
}

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${BUILD_DIR:-$root/build}
out=$root/out/bench
do_build=1
repeat=1
while [ $# -gt 0 ]; do
  case "$1" in
    --no-build) do_build=0 ;;
    --repeat) [ $# -ge 2 ] || { echo "bench: --repeat needs a count" >&2; exit 2; }; repeat=$2; shift ;;
    --out) [ $# -ge 2 ] || { echo "bench: --out needs a directory" >&2; exit 2; }; out=$2; shift ;;
    -h|--help) usage; exit 0 ;;
    *) echo "bench: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
  shift
done
[[ "$repeat" =~ ^[1-9][0-9]*$ ]] || { echo "bench: --repeat must be a positive integer, not '$repeat'" >&2; exit 2; }
case "$build" in /*) ;; *) build=$PWD/$build ;; esac
case "$out" in /*) ;; *) out=$PWD/$out ;; esac
cd "$root"

# --- inputs -----------------------------------------------------------------
missing=()
for f in data/meshes/dragon_vrip_res3.ply.gz data/meshes/dragon_vrip_res4.ply.gz data/meshes/bunny.off \
         data/envmaps/forest.exr; do
  [ -f "$f" ] || missing+=("$f")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "bench: missing data: ${missing[*]}" >&2
  echo "bench: run tools/fetch-data.sh first (it fetches and verifies the meshes and environments)" >&2
  exit 1
fi
command -v python3 >/dev/null 2>&1 || { echo "bench: python3 is needed for the report (apt-get install python3)" >&2; exit 1; }

# --- build ------------------------------------------------------------------
targets=(bench_relight prt-bench-pass1 prt-precompute prt-bench-relight-file prt-bench-tsis prt-pointlight prt-bench-edit)
if [ "$do_build" = 1 ]; then
  echo "bench: building ${targets[*]} (Release) in $build"
  BUILD_DIR=$build BUILD_TYPE=Release "$root/tools/build.sh" "${targets[@]}"
fi
# Commands are shown relative to the repository when the build is inside it.
b=${build#"$root"/}
bench_relight=$b/bin/bench_relight
bench_pass1=$b/bin/prt-bench-pass1
precompute=$b/bin/prt-precompute
bench_file=$b/bin/prt-bench-relight-file
bench_tsis=$b/bin/prt-bench-tsis
pointlight=$b/bin/prt-pointlight
bench_edit=$b/bin/prt-bench-edit
for exe in "$bench_relight" "$bench_pass1" "$precompute" "$bench_file" "$bench_tsis" "$pointlight" "$bench_edit"; do
  [ -x "$exe" ] || { echo "bench: $exe not built (run without --no-build, or tools/build.sh)" >&2; exit 1; }
done

mkdir -p "$out"
o=${out#"$root"/}
: >"$out/commands.tsv"
{
  echo "date=$(date -u +%Y-%m-%dT%H:%M:%SZ)"
  echo "cpu=$(grep -m1 'model name' /proc/cpuinfo 2>/dev/null | sed 's/.*: //')"
  echo "threads=$(nproc)"
  echo "memory_gib=$(awk '/MemTotal/ {printf "%.0f", $2 / 1048576}' /proc/meminfo 2>/dev/null)"
  echo "commit=$(git rev-parse --short HEAD 2>/dev/null || echo unknown)$(git diff --quiet HEAD -- 2>/dev/null || echo '+changes')"
  echo "load_start=$(cut -d' ' -f1-3 /proc/loadavg)"
  echo "repeat=$repeat"
} >"$out/meta.txt"

# run NAME CMD...: runs CMD from the repository root, output to $out/NAME.log.
run() {
  local name=$1; shift
  local started=$SECONDS
  # Arguments separated by \x1f, so the report can quote them for a shell.
  { printf '%s\t' "$name"; printf '%s\x1f' "$@"; printf '\n'; } >>"$out/commands.tsv"
  echo "bench: [$name] $(printf '%q ' "$@")"
  if ! "$@" >"$out/$name.log" 2>&1; then
    echo "bench: [$name] failed; last lines of $o/$name.log:" >&2
    tail -n 20 "$out/$name.log" >&2
    exit 1
  fi
  echo "bench: [$name] done in $((SECONDS - started)) s"
}

run relight "$bench_relight" '--benchmark_filter=RelightVsStream|LoadTransportFile' \
  "--tmp-dir=$o" "--summary-json=$o/relight.json"
# Run K of the once-per-process benchmarks: its logs and JSON carry ".rK" for K > 1.
for k in $(seq 1 "$repeat"); do
  r=; [ "$k" = 1 ] || r=.r$k
  [ "$repeat" = 1 ] || echo "bench: run $k of $repeat of pass 1, the precomputes, the file relights and the cache"
  run "pass1$r" "$bench_pass1" data/meshes/dragon_vrip_res3.ply.gz --samples 2000
  rm -f "$out/precompute$r.json"
  run "precompute$r" "$precompute" data/meshes/dragon_vrip_res4.ply.gz --size-mm 30 --material Marble \
    --components ms,ss -f -q --summary-json "$o/precompute$r.json" -o "$o/dragon4_ms_ss.prt"
  run "relight_file$r" "$bench_file" "$o/dragon4_ms_ss.prt" -e data/envmaps/forest.exr --json "$o/relight_file$r.json"
  run "precompute_folded$r" "$precompute" data/meshes/dragon_vrip_res4.ply.gz --size-mm 30 --material Marble \
    --components ms,ss --fold-ss -f -q -o "$o/dragon4_folded.prt"
  run "relight_file_folded$r" "$bench_file" "$o/dragon4_folded.prt" -e data/envmaps/forest.exr \
    --json "$o/relight_file_folded$r.json"
  run "cache$r" "$pointlight" data/meshes/bunny.off --size-mm 40 -m Marble --light point:30,40,30:0.01 \
    -W 1024 -H 1024 --exposure -1 --method cache --compare-jb -o "$o/cache"
done
run tsis "$bench_tsis" data/meshes/dragon_vrip_res4.ply.gz --size-mm 30 -m Skin2 --light point:-20,40,-60:0.04 \
  -W 512 -H 512 --split hybrid --samples 3600 --repeat 7 --material-change Skin1 --json "$o/tsis.json"
# Live materials on the bunny: the editable file at the defaults against a per-vertex
# plain file, and a blocked editable one (nested lists, 216 per block) against the
# default blocked file.
bunny=(data/meshes/bunny.off --size-mm 30 -m Marble -f -q)
run edit_files_blocked "$precompute" "${bunny[@]}" -o "$o/bunny_blocked.prt"
run edit_files_per_vertex "$precompute" "${bunny[@]}" --block-coefficients 0 -o "$o/bunny_per_vertex.prt"
run edit_files_editable "$precompute" "${bunny[@]}" --editable -o "$o/bunny_editable.prt"
run edit_files_editable_blocked "$precompute" "${bunny[@]}" --editable --block-coefficients 216 \
  -o "$o/bunny_editable_blocked.prt"
run edit "$bench_edit" data/meshes/bunny.off "$o/bunny_editable.prt" data/envmaps/forest.exr \
  --plain "$o/bunny_per_vertex.prt" --repeat 11 --json "$o/edit.json"
run edit_blocked "$bench_edit" data/meshes/bunny.off "$o/bunny_editable_blocked.prt" data/envmaps/forest.exr \
  --plain "$o/bunny_blocked.prt" --repeat 11 --json "$o/edit_blocked.json"
echo "load_end=$(cut -d' ' -f1-3 /proc/loadavg)" >>"$out/meta.txt"
rm -f "$out/dragon4_ms_ss.prt" "$out/dragon4_folded.prt" "$out"/bunny_{blocked,per_vertex,editable,editable_blocked}.prt

python3 "$root/tools/bench_report.py" "$out"
