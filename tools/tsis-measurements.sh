#!/usr/bin/env bash
# tools/tsis-measurements.sh -- the texture-space importance sampling figures of
# docs/point-lights.md and docs/performance.md (Chang et al. 2008 analogues), each
# from prt-bench-tsis (tools/bench/bench_tsis.cpp), median of 5 runs in one process:
#   table2-3.md  fps against N (49 .. 2500) for five meshes at 30 mm, 512 x 512, one
#                point light behind the object, per-vertex sums (the viewer's path):
#                "new light" = irradiance map + shadow maps + draws + sums (Table 2),
#                "sums only" = a still light and a moving camera (Table 3);
#   fig7.md      RMSE against Jensen-Buhler (epsilon 0, per pixel) against N: the
#                dragon (11,102 faces), 30 mm, Skin2, sampling alone and hybrid;
#   fig13.md     Skin1 at 10, 20, 30 mm: sampling alone at N = 900, 3600, 14400
#                against the hybrid at N = 900;
#   fast.md      the goal configuration (atlas 512, L = C = 16, N = 1600) against the
#                settings of the time (atlas 1024, L = C = 20).
# Every run passes those settings and --cluster-angle 0 (every sample summed), the
# defaults when the tables were made; tools/tsis-frames.sh measures today's.
# Needs the fetched meshes (tools/fetch-data.sh) and a Release build in $BUILD_DIR
# (default build/). About 10 minutes on 2 cores. Output: out/tsis-measurements/.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${BUILD_DIR:-$root/build}
out=$root/out/tsis-measurements
bench=$build/bin/prt-bench-tsis
[ -x "$bench" ] || { echo "tsis-measurements: build first (tools/build.sh): $bench is missing" >&2; exit 1; }
mkdir -p "$out"
cd "$root"
m=data/meshes
light_dragon="point:-20,40,-60:0.04"
light_centred="point:-20,26,-60:0.04"
# The settings of the tables in docs/point-lights.md (the defaults of 2026-11-23).
common=(-W 512 -H 512 --size-mm 30 --repeat 5 --cluster-angle 0)
former=(--atlas-size 1024 --rings 20 --ring-samples 20)

{
  echo "# Table 2/3 analogue (sampling alone, per vertex, defaults)"
  for mesh in elephant.off dragon_vrip_res4.ply.gz dragon_vrip_res3.ply.gz armadillo.off bunny.off; do
    light=$light_centred
    case $mesh in dragon*) light=$light_dragon ;; esac
    echo
    "$bench" "$m/$mesh" "${common[@]}" "${former[@]}" -m Skin1 --light "$light" --split sampling 2>/dev/null
  done
  echo
  echo "# The hybrid (local filter 20 x 20 + 1 taps), dragon 11K faces"
  "$bench" "$m/dragon_vrip_res4.ply.gz" "${common[@]}" "${former[@]}" -m Skin1 --light "$light_dragon" --split hybrid 2>/dev/null
} | tee "$out/table2-3.md"

{
  echo "# Fig. 7 analogue: dragon 11,102 faces, 30 mm, Skin2, RMSE (RMS over 3 seeds) against Jensen-Buhler"
  for split in sampling hybrid; do
    echo
    "$bench" "$m/dragon_vrip_res4.ply.gz" "${common[@]}" "${former[@]}" -m Skin2 --light "$light_dragon" --split $split \
      --samples 49,100,169,256,400,900,1600,2500,6400,14400 --reference --seeds 3 2>/dev/null
  done
} | tee "$out/fig7.md"

{
  echo "# Fig. 13 analogue: dragon 11,102 faces, Skin1 at 10, 20, 30 mm"
  for size in 10 20 30; do
    echo
    echo "## $size mm"
    "$bench" "$m/dragon_vrip_res4.ply.gz" -W 512 -H 512 --size-mm $size --repeat 3 "${former[@]}" --cluster-angle 0 \
      -m Skin1 --light "$light_dragon" --split sampling --samples 900,3600,14400 --reference --seeds 3 2>/dev/null
    "$bench" "$m/dragon_vrip_res4.ply.gz" -W 512 -H 512 --size-mm $size --repeat 3 "${former[@]}" --cluster-angle 0 \
      -m Skin1 --light "$light_dragon" --split hybrid --samples 900 --reference --seeds 3 2>/dev/null
  done
} | tee "$out/fig13.md"

{
  echo "# The goal: RMSE <= 0.010 at >= 30 fps, dragon 11,102 faces, 30 mm, Skin2, 512 x 512"
  for cfg in "--atlas-size 1024 --rings 20 --ring-samples 20" "--atlas-size 512 --rings 20 --ring-samples 20" \
             "--atlas-size 512 --rings 16 --ring-samples 16"; do
    echo
    echo "## options: $cfg (shadow map 256)"
    # shellcheck disable=SC2086
    "$bench" "$m/dragon_vrip_res4.ply.gz" "${common[@]}" -m Skin2 --light "$light_dragon" --split hybrid \
      --samples 400,900,1200,1600 --reference --seeds 3 $cfg 2>/dev/null
  done
} | tee "$out/fast.md"
echo "tsis-measurements: wrote $out/{table2-3,fig7,fig13,fast}.md"
