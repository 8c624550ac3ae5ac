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
# COMPONENTS=ms,ss times whole jobs instead: each run then also prints the
# multiple-scattering seconds (samples + pass 1 + pass 2), the job's total and the
# ratio single / multiple scattering (phase factoring counted with single scattering),
# and the medians of that ratio for each binary.
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

components="${COMPONENTS:-ss}"

# One run: prints "seconds cpu rays_per_vertex rays_per_second ms_seconds total_seconds ss_over_ms"
# (the last three 0 without multiple scattering).
run() {
    local bin="$1" tag="$2"
    local own=()
    if [[ "$tag" == before ]]; then read -r -a own <<< "${BEFORE_OPTIONS:-}"; else read -r -a own <<< "${AFTER_OPTIONS:-}"; fi
    local json="$out/${name}_${tag}.json" prt="$out/${name}_${tag}.prt"
    /usr/bin/time -f "%U %S" -o "$out/time.txt" \
        "$bin" "$mesh" --size-mm 30 --components "$components" -q --force -o "$prt" --summary-json "$json" "${extra[@]}" "${own[@]}" \
        > "$out/${name}_${tag}.txt" 2>&1
    python3 - "$json" "$out/time.txt" <<'EOF'
import json, sys
d = json.load(open(sys.argv[1]))["summary"]
u, s = map(float, open(sys.argv[2]).read().split()[-2:])
sec, rays, verts = d["ss_seconds"], d["ss_rays"], d["vertices"]
ms = sum(d[k] or 0.0 for k in ("samples_seconds", "pass1_seconds", "pass2_seconds"))
ss = sec + (d["phase_seconds"] or 0.0)
print(f"{sec:.2f} {u + s:.2f} {rays / verts:.0f} {rays / sec:.3g} {ms:.2f} {d['total_seconds']:.2f} {ss / ms if ms > 0 else 0:.2f}")
EOF
}

echo "mesh $mesh, $runs runs each, options: --size-mm 30 --components $components ${extra[*]}; before: ${BEFORE_OPTIONS:-}; after: ${AFTER_OPTIONS:-}"
printf "%-7s %-3s %10s %10s %14s %10s %8s %9s %8s\n" binary run "SS s" "CPU s" "rays/vertex" "rays/s" "MS s" "total s" "SS/MS"
ratios=() before_ss_ms=() after_ss_ms=()
for ((k = 1; k <= runs; ++k)); do
    b=($(run "$before" before))
    printf "%-7s %-3d %10s %10s %14s %10s %8s %9s %8s\n" before "$k" "${b[@]}"
    a=($(run "$after" after))
    printf "%-7s %-3d %10s %10s %14s %10s %8s %9s %8s\n" after "$k" "${a[@]}"
    ratios+=("$(python3 -c "print(${b[0]} / ${a[0]})")")
    before_ss_ms+=("${b[6]}") after_ss_ms+=("${a[6]}")
done
python3 -c "import statistics, sys; r = [float(x) for x in sys.argv[1:]]; print('speed-up (before / after, single-scattering seconds): median %.2fx, runs %s' % (statistics.median(r), ' '.join('%.2f' % x for x in r)))" "${ratios[@]}"
if [[ "$components" == *ms* ]]; then
    python3 -c "import statistics, sys; n = len(sys.argv) // 2; b = [float(x) for x in sys.argv[1:n + 1]]; a = [float(x) for x in sys.argv[n + 1:]]; print('single / multiple scattering: before median %.2fx (%.2f-%.2f), after median %.2fx (%.2f-%.2f)' % (statistics.median(b), min(b), max(b), statistics.median(a), min(a), max(a)))" "${before_ss_ms[@]}" "${after_ss_ms[@]}"
fi
