#!/usr/bin/env bash
# Installs the built Python module (<build>/python/prt) into a Python's site-packages:
#   tools/install-python.sh                 the user's site of /usr/bin/python3 (~/.local)
#   tools/install-python.sh .venv/bin/python   a venv (made with --system-site-packages,
#                                              so that it sees Debian's numpy)
# BUILD_DIR selects the build (default build/). Build first: tools/build.sh.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build_dir=${BUILD_DIR:-$root/build}
python=${1:-/usr/bin/python3}
case "${1:-}" in -h|--help) sed -n 2,6p "$0" | sed 's/^# \{0,1\}//'; exit 0 ;; esac

package="$build_dir/python/prt"
if ! ls "$package"/_prt*.so > /dev/null 2>&1; then
    echo "install-python: $package: no built module (run tools/build.sh; the module needs python3-dev, python3-numpy and pybind11-dev from tools/setup.sh)" >&2
    exit 1
fi
command -v "$python" > /dev/null 2>&1 || { echo "install-python: $python: no such interpreter" >&2; exit 1; }
# A venv's own site-packages, else the user's site.
target=$("$python" -c 'import site, sys
print(site.getsitepackages()[0] if sys.prefix != sys.base_prefix else site.getusersitepackages())')
module_abi=$(basename "$package"/_prt*.so | sed 's/^_prt\.//; s/\.so$//')
python_abi=$("$python" -c 'import sysconfig; print(sysconfig.get_config_var("SOABI"))')
if [ "$module_abi" != "$python_abi" ]; then
    echo "install-python: the module was built for $module_abi, $python is $python_abi" >&2
    exit 1
fi
mkdir -p "$target"
rm -rf "$target/prt.tmp"
cp -r "$package" "$target/prt.tmp"
rm -rf "$target/prt"
mv "$target/prt.tmp" "$target/prt"
"$python" -c 'import prt, sys; print("install-python: prt installed in", prt.__path__[0], "for", sys.executable)'
