#!/usr/bin/env bash
# Paired timing of the single-scattering pass: two prt-precompute binaries (before,
# after) run back to back on the same mesh, alternating, so a shared machine's load
# hits both alike; prints each run's single-scattering seconds, CPU seconds, rays per
# vertex and rays/s, and the median ratio. docs/single-scattering.md ("Speed").
#
#   tools/ss-bench.sh BEFORE_BINARY AFTER_BINARY [mesh] [runs] [-- extra prt-precompute options]
#
# Defaults: data/meshes/dragon_vrip_res4.ply.gz, 2 runs each, --size-mm 30
# --components ss (single scattering alone: no samples, no multiple scattering).
# BEFORE_OPTIONS / AFTER_OPTIONS (space-separated) go to one binary only, so one build
# can be timed against itself, e.g. the midpoint path rule against the default:
#   BEFORE_OPTIONS="--path-quadrature midpoint" tools/ss-bench.sh B B mesh 2
# Outputs go to ${OUT:-out/ss-bench}.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
before="${1:?usage: tools/ss-bench.sh BEFORE_BINARY AFTER_BINARY [mesh] [runs] [-- options]}"
after="${2:?usage: tools/ss-bench.sh BEFORE_BINARY AFTER_BINARY [mesh] [runs] [-- options]}"
shift 2
mesh="$root/data/meshes/dragon_vrip_res4.ply.gz"
runs=2
if [[ $# -gt 0 && "$1" != "--" ]]; then mesh="$1"; shift; fi
if [[ $# -gt 0 && "$1" != "--" ]]; then runs="$1"; shift; fi
[[ $# -gt 0 && "$1" == "--" ]] && shift
extra=("$@")
out="${OUT:-$root/out/ss-bench}"
mkdir -p "$out"
name="$(basename "$mesh")"
name="${name%%.*}"

# One run: prints "seconds cpu rays_per_vertex rays_per_second".
run() {
    local bin="$1" tag="$2"
    local own=()
    if [[ "$tag" == before ]]; then read -r -a own <<< "${BEFORE_OPTIONS:-}"; else read -r -a own <<< "${AFTER_OPTIONS:-}"; fi
    local json="$out/${name}_${tag}.json" prt="$out/${name}_${tag}.prt"
    /usr/bin/time -f "%U %S" -o "$out/time.txt" \
        "$bin" "$mesh" --size-mm 30 --components ss -q --force -o "$prt" --summary-json "$json" "${extra[@]}" "${own[@]}" \
        > "$out/${name}_${tag}.txt" 2>&1
    python3 - "$json" "$out/time.txt" <<'EOF'
import json, sys
d = json.load(open(sys.argv[1]))["summary"]
u, s = map(float, open(sys.argv[2]).read().split()[-2:])
sec, rays, verts = d["ss_seconds"], d["ss_rays"], d["vertices"]
print(f"{sec:.2f} {u + s:.2f} {rays / verts:.0f} {rays / sec:.3g}")
EOF
}

echo "mesh $mesh, $runs runs each, options: --size-mm 30 --components ss ${extra[*]}; before: ${BEFORE_OPTIONS:-}; after: ${AFTER_OPTIONS:-}"
printf "%-7s %-3s %10s %10s %14s %10s\n" binary run "SS s" "CPU s" "rays/vertex" "rays/s"
ratios=()
for ((k = 1; k <= runs; ++k)); do
    b=($(run "$before" before))
    printf "%-7s %-3d %10s %10s %14s %10s\n" before "$k" "${b[0]}" "${b[1]}" "${b[2]}" "${b[3]}"
    a=($(run "$after" after))
    printf "%-7s %-3d %10s %10s %14s %10s\n" after "$k" "${a[0]}" "${a[1]}" "${a[2]}" "${a[3]}"
    ratios+=("$(python3 -c "print(${b[0]} / ${a[0]})")")
done
python3 -c "import statistics, sys; r = [float(x) for x in sys.argv[1:]]; print('speed-up (before / after, single-scattering seconds): median %.2fx, runs %s' % (statistics.median(r), ' '.join('%.2f' % x for x in r)))" "${ratios[@]}"
