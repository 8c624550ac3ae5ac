#!/usr/bin/env bash
# tools/scaling.sh -- scaling curves of the precomputation and the relight (docs/tools.md).
#
# Runs prt-precompute (with --summary-json) and prt-bench-relight-file on series of
# jobs, collects every JSON into out/scaling/json/, one CSV (out/scaling/scaling.csv)
# and Markdown tables (out/scaling/tables.md), and draws log-log plots with fitted
# slopes (docs/images/scaling_*.png; --quick: out/scaling/images/) when matplotlib is
# installed (tools/setup.sh --plots).
#
# Series (full run; dragon at 30 mm, Marble, defaults unless stated):
#   ms_mesh          multiple scattering: dragon res4, res3, res2, full (5K-437K vertices)
#   ms_cubemap       cubemap 32, 64 (res3)
#   ms_coefficients  coefficients kept per vertex 64, 128, 192, 256 (res3; -k alone: per-vertex files)
#   ms_samples       --samples 5000, 10000, 20000, 40000 (+ the default 9,732) (res3)
#   ss_mesh          isotropic single scattering (--components ss, at sites): res4, res3, res2, full
#   ss_path_samples  --path-samples 2, 3, the default 4, 6, 8 and 32 (res4; Gauss-Legendre rule, adaptive directions)
#   relight          relight time per frame of every file against its bytes
#   pointlights      point lights vs mesh size (dragon res4, res3, res2; 30 mm, Skin2, one
#                    point light): texture-space sampling (prt-bench-tsis, hybrid at its defaults,
#                    512 x 512, per vertex: time per new light position and its stages,
#                    median of 5) and the irradiance cache (prt-pointlight --method cache
#                    --compare-jb, 1024 x 1024: T_cache and Jensen-Buhler's T_JB in the
#                    same run)
set -euo pipefail

usage() {
  cat <<'EOF'
Usage: tools/scaling.sh [--quick] [--no-build] [--keep] [--repeat N] [--out DIR] [--plots DIR]

Full run: every series below (docs/tools.md gives how long it takes; the
single-scattering jobs take most of it). --quick: dragon res4 only with tiny variants,
to test the chain; its plots go to DIR/images, not docs/images.

  --quick       res4 + tiny variants only
  --no-build    use the binaries already in $BUILD_DIR (default build/)
  --keep        keep the transport files (DIR/prt/*.prt; the full set is ~1 GB)
  --repeat N    run every precompute and relight job N times (default 1; the tables
                show the median and the min..max of each time, the plots the medians;
                N times as long)
  --out DIR     output directory (default out/scaling)
  --plots DIR   where the PNG plots go (default docs/images; --quick: DIR/images)
EOF
}

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${BUILD_DIR:-$root/build}
out=$root/out/scaling
plots=
quick=0
do_build=1
keep=0
repeat=1
while [ $# -gt 0 ]; do
  case "$1" in
    --quick) quick=1 ;;
    --no-build) do_build=0 ;;
    --keep) keep=1 ;;
    --repeat) [ $# -ge 2 ] || { echo "scaling: --repeat needs a count" >&2; exit 2; }; repeat=$2; shift ;;
    --out) [ $# -ge 2 ] || { echo "scaling: --out needs a directory" >&2; exit 2; }; out=$2; shift ;;
    --plots) [ $# -ge 2 ] || { echo "scaling: --plots needs a directory" >&2; exit 2; }; plots=$2; shift ;;
    -h|--help) usage; exit 0 ;;
    *) echo "scaling: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
  shift
done
[[ "$repeat" =~ ^[1-9][0-9]*$ ]] || { echo "scaling: --repeat must be a positive integer, not '$repeat'" >&2; exit 2; }
case "$build" in /*) ;; *) build=$PWD/$build ;; esac
case "$out" in /*) ;; *) out=$PWD/$out ;; esac
if [ -z "$plots" ]; then
  if [ "$quick" = 1 ]; then plots=$out/images; else plots=$root/docs/images; fi
fi
case "$plots" in /*) ;; *) plots=$PWD/$plots ;; esac
cd "$root"

m=data/meshes
env=data/envmaps/forest.exr
# name | series (comma-separated) | mesh | extra prt-precompute options
if [ "$quick" = 1 ]; then
  runs=(
    "ms_res4|ms_mesh,ms_cubemap,ms_samples|$m/dragon_vrip_res4.ply.gz|"
    "ms_res4_k128|ms_coefficients|$m/dragon_vrip_res4.ply.gz|-k 128"
    "ms_res4_n16|ms_cubemap|$m/dragon_vrip_res4.ply.gz|--cubemap-size 16"
    "ms_res4_k64|ms_coefficients|$m/dragon_vrip_res4.ply.gz|-k 64"
    "ms_res4_s2000|ms_samples|$m/dragon_vrip_res4.ply.gz|--samples 2000"
    "ms_res4_s4000|ms_samples|$m/dragon_vrip_res4.ply.gz|--samples 4000"
    "ss_res4_n16_p2|ss_mesh,ss_path_samples|$m/dragon_vrip_res4.ply.gz|--components ss --cubemap-size 16 --path-samples 2"
    "ss_res4_n16_p4|ss_path_samples|$m/dragon_vrip_res4.ply.gz|--components ss --cubemap-size 16 --path-samples 4"
  )
  pl_runs=("pl_res4|$m/dragon_vrip_res4.ply.gz")
else
  runs=(
    "ms_res4|ms_mesh|$m/dragon_vrip_res4.ply.gz|"
    "ms_res3|ms_mesh,ms_cubemap,ms_samples|$m/dragon_vrip_res3.ply.gz|"
    "ms_res2|ms_mesh|$m/dragon_vrip_res2.ply.gz|"
    "ms_full|ms_mesh|$m/dragon_vrip.ply.gz|"
    "ms_res3_n64|ms_cubemap|$m/dragon_vrip_res3.ply.gz|--cubemap-size 64"
    "ms_res3_k64|ms_coefficients|$m/dragon_vrip_res3.ply.gz|-k 64"
    "ms_res3_k128|ms_coefficients|$m/dragon_vrip_res3.ply.gz|-k 128"
    "ms_res3_k192|ms_coefficients|$m/dragon_vrip_res3.ply.gz|-k 192"
    "ms_res3_k256|ms_coefficients|$m/dragon_vrip_res3.ply.gz|-k 256"
    "ms_res3_s5000|ms_samples|$m/dragon_vrip_res3.ply.gz|--samples 5000"
    "ms_res3_s10000|ms_samples|$m/dragon_vrip_res3.ply.gz|--samples 10000"
    "ms_res3_s20000|ms_samples|$m/dragon_vrip_res3.ply.gz|--samples 20000"
    "ms_res3_s40000|ms_samples|$m/dragon_vrip_res3.ply.gz|--samples 40000"
    "ss_res4|ss_mesh,ss_path_samples|$m/dragon_vrip_res4.ply.gz|--components ss"
    "ss_res4_p2|ss_path_samples|$m/dragon_vrip_res4.ply.gz|--components ss --path-samples 2"
    "ss_res4_p3|ss_path_samples|$m/dragon_vrip_res4.ply.gz|--components ss --path-samples 3"
    "ss_res4_p6|ss_path_samples|$m/dragon_vrip_res4.ply.gz|--components ss --path-samples 6"
    "ss_res3|ss_mesh|$m/dragon_vrip_res3.ply.gz|--components ss"
    "ss_res2|ss_mesh|$m/dragon_vrip_res2.ply.gz|--components ss"
    "ss_full|ss_mesh|$m/dragon_vrip.ply.gz|--components ss"
    "ss_res4_p8|ss_path_samples|$m/dragon_vrip_res4.ply.gz|--components ss --path-samples 8"
    "ss_res4_p32|ss_path_samples|$m/dragon_vrip_res4.ply.gz|--components ss --path-samples 32"
  )
  pl_runs=("pl_res4|$m/dragon_vrip_res4.ply.gz" "pl_res3|$m/dragon_vrip_res3.ply.gz"
           "pl_res2|$m/dragon_vrip_res2.ply.gz")
fi

# --- inputs -----------------------------------------------------------------
missing=()
for r in "${runs[@]}"; do
  IFS='|' read -r _ _ mesh _ <<<"$r"
  [ -f "$mesh" ] || case " ${missing[*]-} " in *" $mesh "*) ;; *) missing+=("$mesh") ;; esac
done
[ -f "$env" ] || missing+=("$env")
if [ ${#missing[@]} -gt 0 ]; then
  echo "scaling: missing data: ${missing[*]}" >&2
  echo "scaling: run tools/fetch-data.sh first (it fetches and verifies the meshes and environments)" >&2
  exit 1
fi
command -v python3 >/dev/null 2>&1 || { echo "scaling: python3 is needed for the tables (apt-get install python3)" >&2; exit 1; }
# Debian's python3-matplotlib is installed for /usr/bin/python3 (another python3 may be first in PATH).
py=python3
for p in /usr/bin/python3 python3; do
  if "$p" -c 'import matplotlib' >/dev/null 2>&1; then py=$p; break; fi
done

# --- build ------------------------------------------------------------------
targets=(prt-precompute prt-bench-relight-file prt-bench-tsis prt-pointlight)
if [ "$do_build" = 1 ]; then
  echo "scaling: building ${targets[*]} (Release) in $build"
  BUILD_DIR=$build BUILD_TYPE=Release "$root/tools/build.sh" "${targets[@]}"
fi
b=${build#"$root"/}
precompute=$b/bin/prt-precompute
bench_file=$b/bin/prt-bench-relight-file
bench_tsis=$b/bin/prt-bench-tsis
pointlight=$b/bin/prt-pointlight
for exe in "$precompute" "$bench_file" "$bench_tsis" "$pointlight"; do
  [ -x "$exe" ] || { echo "scaling: $exe not built (run without --no-build, or tools/build.sh)" >&2; exit 1; }
done

# --- runs -------------------------------------------------------------------
mkdir -p "$out/json" "$out/prt" "$out/logs"
o=${out#"$root"/}
manifest=$out/manifest.tsv
printf 'name\tseries\tprecompute\trelight\trepeats\n' >"$manifest"
failed=0
i=0
start_all=$SECONDS
for r in "${runs[@]}"; do
  IFS='|' read -r name series mesh extra <<<"$r"
  i=$((i + 1))
  prt=$o/prt/$name.prt
  # shellcheck disable=SC2206
  extra_args=($extra)
  # Repeat k writes NAME.json (k = 1) or NAME.rK.json, and the relight's beside it.
  ok=1
  for k in $(seq 1 "$repeat"); do
    tag=$name; [ "$k" = 1 ] || tag=$name.r$k
    json=$o/json/$tag.json
    rjson=$o/json/$tag.relight.json
    log=$out/logs/$tag.log
    rm -f "$json" "$rjson"
    pre_cmd=("$precompute" "$mesh" --size-mm 30 --material Marble "${extra_args[@]}" -f -q
             --summary-json "$json" -o "$prt")
    rel_cmd=("$bench_file" "$prt" -e "$env" --json "$rjson")
    [ "$k" = 1 ] && printf '%s\t%s\t%s\t%s\t%s\n' "$name" "$series" "${pre_cmd[*]}" "${rel_cmd[*]}" "$repeat" >>"$manifest"
    started=$SECONDS
    printf 'scaling: [%d/%d] %s (run %d of %d): %s\n' "$i" "${#runs[@]}" "$name" "$k" "$repeat" "${pre_cmd[*]}"
    if "${pre_cmd[@]}" >"$log" 2>&1 && "${rel_cmd[@]}" >>"$log" 2>&1; then
      printf 'scaling: [%d/%d] %s (run %d of %d) done in %d s\n' "$i" "${#runs[@]}" "$name" "$k" "$repeat" \
        $((SECONDS - started))
    else
      echo "scaling: [$i/${#runs[@]}] $name (run $k) FAILED; last lines of $log:" >&2
      tail -n 10 "$log" >&2
      ok=0
    fi
  done
  [ "$ok" = 1 ] || failed=$((failed + 1))
  [ "$keep" = 1 ] || rm -f "$prt"
done

# Point lights: one scene per mesh, the same light and material for every size.
pl_manifest=$out/pointlights.tsv
printf 'name\tmesh\ttsis\tcache\n' >"$pl_manifest"
light=(--size-mm 30 -m Skin2 --light point:-20,40,-60:0.04)
for r in "${pl_runs[@]}"; do
  IFS='|' read -r name mesh <<<"$r"
  i=$((i + 1))
  rm -f "$out/json/$name.tsis.json"
  tsis_cmd=("$bench_tsis" "$mesh" "${light[@]}" -W 512 -H 512 --split hybrid --samples 3600 --repeat 5
            --json "$o/json/$name.tsis.json")
  cache_cmd=("$pointlight" "$mesh" "${light[@]}" -W 1024 -H 1024 --method cache --compare-jb
             -o "$o/prt/$name.cache")
  printf '%s\t%s\t%s\t%s\n' "$name" "$mesh" "${tsis_cmd[*]}" "${cache_cmd[*]}" >>"$pl_manifest"
  started=$SECONDS
  printf 'scaling: [%d] %s: point lights on %s\n' "$i" "$name" "$mesh"
  if "${tsis_cmd[@]}" >"$out/logs/$name.tsis.log" 2>&1 && "${cache_cmd[@]}" >"$out/logs/$name.cache.log" 2>&1; then
    printf 'scaling: [%d] %s done in %d s\n' "$i" "$name" $((SECONDS - started))
  else
    echo "scaling: [$i] $name FAILED; see $o/logs/$name.tsis.log and $name.cache.log" >&2
    failed=$((failed + 1))
  fi
  [ "$keep" = 1 ] || rm -f "$out/prt/$name".cache*
done
echo "scaling: ${#runs[@]} + ${#pl_runs[@]} runs in $((SECONDS - start_all)) s, $failed failed"

mkdir -p "$plots"
"$py" "$root/tools/plot_scaling.py" --dir "$out" --plots "$plots"
[ "$failed" = 0 ] || { echo "scaling: $failed run(s) failed (see $o/logs/)" >&2; exit 1; }
