#!/usr/bin/env bash
# The cost of a live material change under point lights (docs/point-lights.md, "Live
# material and size"), on the dragon res4 at the texture-space defaults:
#   1. RUNS runs of `prt-bench-tsis --material-change` (setMaterial and the per-vertex
#      sums after it, medians of 14 changes each; the steady frame's own sums beside);
#   2. RUNS runs of the viewer under Xvfb with a scripted edit (--edit-after) on an
#      editable file of the same mesh: its "point-light material changes" line, the
#      worker's time plus the upload before the frame that shows the edit.
# Prints one line per run and the median (min..max) of each column.
# Usage: tools/material-change.sh   (RUNS=5, PRT_BUILD_DIR=build, OUT=out/material-change)
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$root"
bin=${PRT_BUILD_DIR:-build}/bin
runs=${RUNS:-5}
out=${OUT:-out/material-change}
mesh=data/meshes/dragon_vrip_res4.ply.gz
light=point:-20,40,-60:0.04
for tool in prt-bench-tsis prt-precompute prt-relight; do
  [ -x "$bin/$tool" ] || { echo "material-change: $bin/$tool not built (tools/build.sh $tool)" >&2; exit 1; }
done
[ -f "$mesh" ] || { echo "material-change: $mesh missing (tools/fetch-data.sh)" >&2; exit 1; }
mkdir -p "$out"

median() { sort -g | awk '{v[NR] = $1} END {m = (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2;
                                           printf "%.2f (%.2f..%.2f)", m, v[1], v[NR]}'; }

echo "== prt-bench-tsis --material-change Skin1 (Skin2 <-> Skin1), $runs runs"
: > "$out/bench.txt"
for i in $(seq 1 "$runs"); do
  "$bin/prt-bench-tsis" "$mesh" --size-mm 30 -m Skin2 --light "$light" -W 512 -H 512 --split hybrid \
      --repeat 7 --samples 3600 --material-change Skin1 > "$out/bench_$i.log" 2>&1
  awk '/^\| 3600/ {sums = $10} /hybrid setMaterial/ {sm = $4} /hybrid per-vertex sums after/ {after = $10}
       END {printf "%s %s %s %.3f\n", sm, after, sums, sm + after}' "$out/bench_$i.log" | tee -a "$out/bench.txt"
done
echo "setMaterial ms:              $(awk '{print $1}' "$out/bench.txt" | median)"
echo "sums after it ms:            $(awk '{print $2}' "$out/bench.txt" | median)"
echo "a steady frame's sums ms:    $(awk '{print $3}' "$out/bench.txt" | median)"
echo "setMaterial + sums ms:       $(awk '{print $4}' "$out/bench.txt" | median)"

if ! command -v xvfb-run > /dev/null; then
  echo "material-change: xvfb-run not found: the viewer's part is skipped" >&2
  exit 0
fi
echo "== prt-relight view, scripted edit Skin2 -> Skin1, $runs runs"
ed=$out/dragon4_editable.prt
[ -f "$ed" ] || "$bin/prt-precompute" "$mesh" --size-mm 30 -m Skin2 --editable -q -o "$ed"
: > "$out/viewer.txt"
for i in $(seq 1 "$runs"); do
  xvfb-run -a "$bin/prt-relight" view "$mesh" -t "$ed" --light "$light" -W 512 -H 512 --frames 8 \
      --edit-after 3 --edit-material Skin1 > "$out/viewer_$i.log" 2>&1 || true
  line=$(grep "^point-light material changes:" "$out/viewer_$i.log" || true)
  [ -n "$line" ] || { cat "$out/viewer_$i.log" >&2; echo "material-change: no material change in run $i" >&2; exit 1; }
  echo "$line"
  echo "$line" | sed -E 's/.*mean ([0-9.]+) ms before the frame \(setMaterial ([0-9.]+) \+ per-vertex sums ([0-9.]+).*/\1 \2 \3/' \
      >> "$out/viewer.txt"
done
echo "viewer, before the frame ms: $(awk '{print $1}' "$out/viewer.txt" | median)"
echo "viewer, setMaterial ms:      $(awk '{print $2}' "$out/viewer.txt" | median)"
echo "viewer, sums ms:             $(awk '{print $3}' "$out/viewer.txt" | median)"
