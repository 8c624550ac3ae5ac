#!/usr/bin/env bash
# tools/eye-path-table.sh -- single scattering alone along the eye's path against
# prt-reference's refracted-path Monte Carlo (docs/single-scattering.md, "Along the
# eye's path"). Per case: prt-precompute --components ss at the defaults; prt-relight
# render --components ss along the eye's path (--ss-path refracted, the default) and
# along the inward normal (--ss-path normal, as precomputed); two references, the true
# refracted path and Wang's inward normal, with different seeds; prt-compare of each
# pair; and the environment cut into directional lights at a low --sun-threshold
# (single scattering per pixel along the eye's ray). Writes table.md and table.tsv (raw and noise-corrected relative RMSE, mean
# ratios) into the output directory and keeps every file and log there.
set -euo pipefail

usage() {
  cat <<'EOF'
Usage: tools/eye-path-table.sh [--out DIR] [--reuse] [--ss-samples S] [--lights-threshold K] [CASE ...]

CASE is MESH:ENVIRONMENT:G:SIZE[:K], MESH a file stem in data/meshes, ENVIRONMENT a stem
in data/envmaps, G the Henyey-Greenstein g (0: isotropic), SIZE the frame's width and
height, K the phase terms of g != 0 (default: prt-precompute's, 4). Default cases: dragon_vrip_res4:sunset:0:96
bunny:forest:0:128 bunny:forest:0.25:128 bunny:forest:-0.25:128 (Marble, 30 mm).

  --out DIR        output directory (default out/eye-path)
  --reuse          keep the transport files and references DIR already holds (made by
                   an earlier run of the same commit and options: not checked)
  --ss-samples S   the references' path samples per pixel (default 256)
  --lights-threshold K
                   the per-pixel column: prt-relight render --sun-split --sun-threshold K,
                   the environment above K x its mean luminance as directional lights
                   whose single scattering is traced per pixel along the eye's ray
                   (default 0.01: about 99% of the light)

About 15 minutes for the default cases on 2 cores. Needs a build (tools/build.sh) and
the data (tools/fetch-data.sh).
EOF
}

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${BUILD_DIR:-$root/build}
out=$root/out/eye-path
reuse=0
samples=256
lightsThreshold=0.01
cases=()
while [ $# -gt 0 ]; do
  case "$1" in
    --out) [ $# -ge 2 ] || { echo "eye-path-table: --out needs a directory" >&2; exit 2; }; out=$2; shift ;;
    --reuse) reuse=1 ;;
    --ss-samples) [ $# -ge 2 ] || { echo "eye-path-table: --ss-samples needs a number" >&2; exit 2; }; samples=$2; shift ;;
    --lights-threshold) [ $# -ge 2 ] || { echo "eye-path-table: --lights-threshold needs a number" >&2; exit 2; }; lightsThreshold=$2; shift ;;
    -h|--help) usage; exit 0 ;;
    -*) echo "eye-path-table: unknown option '$1' (see --help)" >&2; exit 2 ;;
    *) cases+=("$1") ;;
  esac
  shift
done
[[ "$samples" =~ ^[1-9][0-9]*$ ]] || { echo "eye-path-table: --ss-samples must be a positive integer, not '$samples'" >&2; exit 2; }
[ ${#cases[@]} -gt 0 ] || cases=(dragon_vrip_res4:sunset:0:96 bunny:forest:0:128 bunny:forest:0.25:128 bunny:forest:-0.25:128)
for tool in prt-precompute prt-relight prt-reference prt-compare; do
  [ -x "$build/bin/$tool" ] || { echo "eye-path-table: build first (tools/build.sh): $build/bin/$tool is missing" >&2; exit 1; }
done
mkdir -p "$out"

run() {  # run LOG COMMAND...: the command's output into LOG, a one-line error on failure
  local log=$1; shift
  "$@" > "$log" 2>&1 || { echo "eye-path-table: $(basename "$1") failed (see $log)" >&2; exit 1; }
}
rmse() { awk '$1 == "overall" { print $2 }' "$1"; }
ratio() { awk '$1 == "overall" { print $NF }' "$1"; }
noise() { grep -oE 'expected relative RMSE from Monte Carlo noise [0-9.]+%' "$1" | tail -1 | grep -oE '[0-9.]+' || echo 0; }

tsv=$out/table.tsv
printf 'mesh\tenvironment\tg\tterms\tsize\tlights_vs_refracted\tlights_ratio\tlights_seconds\teye_vs_refracted\teye_ratio\tnormal_vs_refracted\tnormal_ratio\tprecomputed_vs_normal_path\tpaths\trefracted_noise\tnormal_noise\tss_seconds\tss_bytes\n' > "$tsv.tmp"
start=$SECONDS
n=0
for c in "${cases[@]}"; do
  IFS=: read -r stem env g size terms <<< "$c"
  [ -n "${size:-}" ] || { echo "eye-path-table: case '$c' is not MESH:ENVIRONMENT:G:SIZE" >&2; exit 2; }
  mesh=$(ls "$root"/data/meshes/"$stem".* 2>/dev/null | head -1 || true)
  envmap=$root/data/envmaps/$env.exr
  [ -n "$mesh" ] && [ -f "$envmap" ] || { echo "eye-path-table: case '$c': data missing (run tools/fetch-data.sh)" >&2; exit 1; }
  n=$((n + 1))
  phase=()
  file=${stem}_g$g
  if [ -n "${terms:-}" ]; then phase=(--phase-terms "$terms"); file=${file}_k$terms; fi
  tag=${env}_$file
  prt=$out/$file.prt
  if [ "$reuse" = 0 ] || [ ! -f "$prt" ]; then
    echo "eye-path-table: [$n/${#cases[@]}] precomputing $file"
    run "$out/$file.precompute.log" "$build/bin/prt-precompute" "$mesh" --size-mm 30 --material Marble \
      --components ss --g "$g" "${phase[@]}" -f -o "$prt"
  fi
  common=("$mesh" -t "$prt" -e "$envmap" -W "$size" -H "$size")
  run "$out/$tag.eye.log" "$build/bin/prt-relight" render "${common[@]}" --components ss -o "$out/$tag.eye"
  run "$out/$tag.normal.log" "$build/bin/prt-relight" render "${common[@]}" --components ss --ss-path normal \
    -o "$out/$tag.normal"
  run "$out/$tag.lights.log" "$build/bin/prt-relight" render "${common[@]}" --components ss --sun-split \
    --sun-threshold "$lightsThreshold" -o "$out/$tag.lights"
  for path in refracted normal; do
    seed=1; [ "$path" = normal ] && seed=2
    ref=$out/${tag}.reference_$path
    if [ "$reuse" = 0 ] || [ ! -f "$ref.exr" ]; then
      echo "eye-path-table: [$n/${#cases[@]}] $tag: reference along the $path path ($samples path samples)"
      run "$ref.log" "$build/bin/prt-reference" "${common[@]}" --components ss --ss-path "$path" \
        --ss-samples "$samples" --mc-seed "$seed" -o "$ref"
    fi
  done
  run "$out/$tag.eye.compare" "$build/bin/prt-compare" "$out/$tag.eye.exr" "$out/$tag.reference_refracted.exr" \
    --heatmap "$out/$tag.eye_error.png"
  run "$out/$tag.normal.compare" "$build/bin/prt-compare" "$out/$tag.normal.exr" "$out/$tag.reference_refracted.exr" \
    --heatmap "$out/$tag.normal_error.png"
  run "$out/$tag.lights.compare" "$build/bin/prt-compare" "$out/$tag.lights.exr" "$out/$tag.reference_refracted.exr" \
    --heatmap "$out/$tag.lights_error.png"
  run "$out/$tag.own.compare" "$build/bin/prt-compare" "$out/$tag.normal.exr" "$out/$tag.reference_normal.exr"
  run "$out/$tag.paths.compare" "$build/bin/prt-compare" "$out/$tag.reference_normal.exr" \
    "$out/$tag.reference_refracted.exr"
  ssTime=$(grep -oE '^single scattering ([0-9]+ min )?[0-9.]+ s' "$out/$file.precompute.log" | head -1 | sed 's/^single scattering //' || true)
  lightsTime=$(grep -oE '^done: 1 frame in [0-9.]+ s' "$out/$tag.lights.log" | grep -oE '[0-9.]+ s$' | sed 's/ s$//' || true)
  printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\n' "$stem" "$env" "$g" "${terms:-}" "$size" \
    "$(rmse "$out/$tag.lights.compare")" "$(ratio "$out/$tag.lights.compare")" "${lightsTime:-?}" \
    "$(rmse "$out/$tag.eye.compare")" "$(ratio "$out/$tag.eye.compare")" \
    "$(rmse "$out/$tag.normal.compare")" "$(ratio "$out/$tag.normal.compare")" \
    "$(rmse "$out/$tag.own.compare")" "$(rmse "$out/$tag.paths.compare")" \
    "$(noise "$out/$tag.reference_refracted.log")" "$(noise "$out/$tag.reference_normal.log")" \
    "${ssTime:-?}" "$(stat -c %s "$prt")" >> "$tsv.tmp"
  echo "eye-path-table: [$n/${#cases[@]}] $tag done; $((SECONDS - start)) s"
done
mv "$tsv.tmp" "$tsv"

python3 - "$tsv" "$out/table.md" "$samples" "$lightsThreshold" <<'PY'
import csv, math, os, sys
tsv, md, samples, threshold = sys.argv[1:]
rows = list(csv.DictReader(open(tsv), delimiter="\t"))
def pct(x):
    return f"{100 * x:.1f}%"
def corrected(r, *floors):
    v = r * r - sum(f * f for f in floors)
    return math.sqrt(v) if v > 0 else 0.0
lines = [f"Single scattering alone (Marble, 30 mm) against prt-reference along the true refracted path "
         f"({samples} path samples per pixel): overall linear relative RMSE over the object's pixels, raw / "
         "corrected for the references' Monte Carlo noise (sqrt(rmse^2 - noise^2), both references' for the "
         "reference-to-reference row), and the mean ratio; the single-scattering pass's time and the file's size. "
         f"Per pixel: `--sun-split --sun-threshold {threshold}`, and the frame's time.", "",
         "| mesh | environment | g (phase terms) | per pixel (environment as lights) | eye's path (default) | inward normal (Wang) | precomputed vs its own "
         "normal-path reference | normal path vs refracted path (references) | noise (refracted / normal) | pass | file |",
         "|---|---|---|---|---|---|---|---|---|---|---|"]
for r in rows:
    nr, nn = float(r["refracted_noise"]) / 100, float(r["normal_noise"]) / 100
    eye, nor = float(r["eye_vs_refracted"]), float(r["normal_vs_refracted"])
    own, paths = float(r["precomputed_vs_normal_path"]), float(r["paths"])
    lights = float(r["lights_vs_refracted"])
    g = r["g"] if float(r["g"]) == 0 else f"{r['g']} ({r['terms'] or 4})"
    lines.append(f"| {r['mesh']} | {r['environment']} ({r['size']}^2) | {g} | {pct(lights)} / **{pct(corrected(lights, nr))}**, "
                 f"{float(r['lights_ratio']):.3f}, {r['lights_seconds']} s | {pct(eye)} / **{pct(corrected(eye, nr))}**, "
                 f"{float(r['eye_ratio']):.3f} | {pct(nor)} / {pct(corrected(nor, nr))}, {float(r['normal_ratio']):.3f} | "
                 f"{pct(own)} / {pct(corrected(own, nn))} | {pct(paths)} / {pct(corrected(paths, nr, nn))} | "
                 f"{pct(nr)} / {pct(nn)} | {r['ss_seconds']} | {int(r['ss_bytes']) / 1e6:.1f} MB |")
text = "\n".join(lines) + "\n"
with open(md + ".tmp", "w") as f:
    f.write(text)
os.replace(md + ".tmp", md)
print(text)
PY
echo "eye-path-table: ${#cases[@]} cases in $((SECONDS - start)) s; table in $out/table.md"
