#!/usr/bin/env bash
# tools/environment-table.sh -- the precomputed render against prt-reference under every
# fetched environment (docs/fidelity.md, "Every environment"). For each scene (a mesh and
# a material, 30 mm) one prt-precompute at the defaults; then, per environment, a 256 x 256
# prt-relight render and prt-reference's independent render of the same frame (its own
# samples and seed), compared by prt-compare (overall linear relative RMSE over the
# object's pixels). Writes table.md (scene x environment) and table.tsv (one row per cell
# with the reference's noise floor and discretisation estimate) into the output
# directory, and keeps every file and log there.
set -euo pipefail

usage() {
  cat <<'EOF'
Usage: tools/environment-table.sh [--out DIR] [--reuse] [--size W] [--precompute OPTIONS] [--render OPTIONS] [SCENE ...]

SCENE is MESH:MATERIAL, MESH a file stem in data/meshes (bunny, dragon_vrip_res3, ...),
MATERIAL a name of prt-precompute --material. Default scenes: bunny:Marble bunny:Skin1
bunny:Ketchup bunny:Wholemilk dragon_vrip_res3:Marble. Every environment in
data/envmaps/*.exr.

  --out DIR   output directory (default out/environments)
  --reuse     keep the transport files and references DIR already holds (made by an
              earlier run of the same commit and options: not checked); the table marks
              the cells whose reference was reused. Default: everything is made again.
  --size W    frame width and height (default 256)
  --precompute OPTIONS
              more prt-precompute options for every scene, one word list (e.g.
              "--sh-terms 25"); the references do not depend on them
  --render OPTIONS
              more prt-relight render options for every frame, one word list (e.g.
              "--sun-split"); the references do not depend on them

About 30 s per reference on the bunny at 256 x 256 on 2 cores (AVX2); the default set
(5 scenes x 8 environments) takes about 20-25 minutes. Needs a build (tools/build.sh)
and the data (tools/fetch-data.sh).
EOF
}

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${BUILD_DIR:-$root/build}
out=$root/out/environments
reuse=0
size=256
extra=()
render_extra=()
scenes=()
while [ $# -gt 0 ]; do
  case "$1" in
    --out) [ $# -ge 2 ] || { echo "environment-table: --out needs a directory" >&2; exit 2; }; out=$2; shift ;;
    --reuse) reuse=1 ;;
    --size) [ $# -ge 2 ] || { echo "environment-table: --size needs a number" >&2; exit 2; }; size=$2; shift ;;
    --precompute) [ $# -ge 2 ] || { echo "environment-table: --precompute needs options" >&2; exit 2; }
                  read -r -a extra <<< "$2"; shift ;;
    --render) [ $# -ge 2 ] || { echo "environment-table: --render needs options" >&2; exit 2; }
              read -r -a render_extra <<< "$2"; shift ;;
    -h|--help) usage; exit 0 ;;
    -*) echo "environment-table: unknown option '$1' (see --help)" >&2; exit 2 ;;
    *) scenes+=("$1") ;;
  esac
  shift
done
[[ "$size" =~ ^[1-9][0-9]*$ ]] || { echo "environment-table: --size must be a positive integer, not '$size'" >&2; exit 2; }
[ ${#scenes[@]} -gt 0 ] || scenes=(bunny:Marble bunny:Skin1 bunny:Ketchup bunny:Wholemilk dragon_vrip_res3:Marble)
for tool in prt-precompute prt-relight prt-reference prt-compare; do
  [ -x "$build/bin/$tool" ] || { echo "environment-table: build first (tools/build.sh): $build/bin/$tool is missing" >&2; exit 1; }
done
envs=()
for e in "$root"/data/envmaps/*.exr; do [ -f "$e" ] && envs+=("$e"); done
[ ${#envs[@]} -gt 0 ] || { echo "environment-table: no environments in data/envmaps (run tools/fetch-data.sh)" >&2; exit 1; }
meshes=()
for s in "${scenes[@]}"; do
  [[ "$s" == *:* ]] || { echo "environment-table: scene '$s' is not MESH:MATERIAL" >&2; exit 2; }
  stem=${s%%:*}
  mesh=$(ls "$root"/data/meshes/"$stem".* 2>/dev/null | head -1 || true)
  [ -n "$mesh" ] || { echo "environment-table: no mesh data/meshes/$stem.* (run tools/fetch-data.sh)" >&2; exit 1; }
  meshes+=("$mesh")
done
mkdir -p "$out"
tsv=$out/table.tsv
printf 'mesh\tmaterial\tenvironment\trel_rmse\tmean_ratio\treference_noise\treference_discretisation\treused\n' > "$tsv.tmp"
start=$SECONDS
cells=$(( ${#scenes[@]} * ${#envs[@]} ))
cell=0
for k in "${!scenes[@]}"; do
  s=${scenes[$k]}
  mesh=${meshes[$k]}
  stem=${s%%:*}
  mat=${s#*:}
  tag=${stem}_$mat
  prt=$out/$tag.prt
  if [ "$reuse" = 0 ] || [ ! -f "$prt" ]; then
    echo "environment-table: precomputing $tag"
    "$build/bin/prt-precompute" "$mesh" --size-mm 30 --material "$mat" "${extra[@]}" -f -q -o "$prt" > "$out/$tag.precompute.log" 2>&1 \
      || { echo "environment-table: prt-precompute failed for $tag (see $out/$tag.precompute.log)" >&2; exit 1; }
  fi
  for env in "${envs[@]}"; do
    e=$(basename "$env" .exr)
    cell=$((cell + 1))
    frame=$out/${tag}_$e
    ref=$out/${tag}_${e}_reference
    "$build/bin/prt-relight" render "$mesh" -t "$prt" -e "$env" -W "$size" -H "$size" "${render_extra[@]}" -o "$frame" > "$frame.log" 2>&1 \
      || { echo "environment-table: prt-relight failed ($frame.log)" >&2; exit 1; }
    reused=no
    if [ "$reuse" = 1 ] && [ -f "$ref.exr" ] && [ -f "$ref.log" ]; then
      reused=yes
    else
      "$build/bin/prt-reference" "$mesh" -t "$prt" -e "$env" -W "$size" -H "$size" -o "$ref" > "$ref.log" 2>&1 \
        || { echo "environment-table: prt-reference failed ($ref.log)" >&2; exit 1; }
    fi
    "$build/bin/prt-compare" "$frame.exr" "$ref.exr" > "$frame.compare.log" 2>&1 \
      || { echo "environment-table: prt-compare failed ($frame.compare.log)" >&2; exit 1; }
    rmse=$(awk '$1 == "overall" { print $2 }' "$frame.compare.log")
    ratio=$(awk '$1 == "overall" { print $NF }' "$frame.compare.log")
    noise=$(grep -oE 'total noise: expected relative RMSE from Monte Carlo noise [0-9.]+%' "$ref.log" | grep -oE '[0-9.]+%$' || true)
    disc=$(grep -oE 'estimated remaining error [0-9.]+%' "$ref.log" | grep -oE '[0-9.]+%$' || true)
    printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\n' "$stem" "$mat" "$e" "$rmse" "$ratio" "$noise" "$disc" "$reused" >> "$tsv.tmp"
    elapsed=$((SECONDS - start))
    printf 'environment-table: [%d/%d] %s under %s: %s (reference noise %s, discretisation %s%s); %d s, about %d s left\n' \
      "$cell" "$cells" "$tag" "$e" "$(awk -v r="$rmse" 'BEGIN { printf "%.2f%%", 100 * r }')" "${noise:-?}" "${disc:-?}" \
      "$([ "$reused" = yes ] && echo ', reused' || true)" "$elapsed" $(( elapsed * (cells - cell) / cell ))
  done
done
mv "$tsv.tmp" "$tsv"

python3 - "$tsv" "$out/table.md" "$size" "${extra[*]}" "${render_extra[*]}" <<'PY'
import csv, os, sys
tsv, md, size, precompute, render = sys.argv[1:]
rows = list(csv.DictReader(open(tsv), delimiter="\t"))
envs = sorted({r["environment"] for r in rows})
scenes = []
for r in rows:
    if (r["mesh"], r["material"]) not in scenes:
        scenes.append((r["mesh"], r["material"]))
cell = {(r["mesh"], r["material"], r["environment"]): r for r in rows}
options = "".join(f"; {tool} {opts}" for tool, opts in (("prt-precompute", precompute), ("prt-relight render", render)) if opts)
lines = [f"prt-relight render against prt-reference, {size} x {size}, 30 mm, defaults{options}: overall linear "
         "relative RMSE over the object's pixels (prt-compare). * = reference reused from an earlier run.", "",
         "| mesh | material | " + " | ".join(envs) + " | worst |",
         "|---|---|" + "---|" * (len(envs) + 1)]
for m, mat in scenes:
    vals, worst = [], 0.0
    for e in envs:
        r = cell.get((m, mat, e))
        if not r:
            vals.append("")
            continue
        v = 100 * float(r["rel_rmse"])
        worst = max(worst, v)
        vals.append(f"{v:.2f}%" + ("*" if r["reused"] == "yes" else ""))
    lines.append(f"| {m} | {mat} | " + " | ".join(vals) + f" | **{worst:.2f}%** |")
lines += ["", "The references' own noise floor / discretisation estimate (prt-reference's log):", "",
          "| mesh | material | " + " | ".join(envs) + " |", "|---|---|" + "---|" * len(envs)]
for m, mat in scenes:
    vals = []
    for e in envs:
        r = cell.get((m, mat, e))
        vals.append(f"{r['reference_noise']} / {r['reference_discretisation']}" if r else "")
    lines.append(f"| {m} | {mat} | " + " | ".join(vals) + " |")
text = "\n".join(lines) + "\n"
with open(md + ".tmp", "w") as f:
    f.write(text)
os.replace(md + ".tmp", md)
print(text)
PY
echo "environment-table: ${#scenes[@]} scenes x ${#envs[@]} environments in $((SECONDS - start)) s; table in $out/table.md"
