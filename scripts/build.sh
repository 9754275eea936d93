#!/usr/bin/env bash
# Configures and builds envkit (Release) into ${ENVKIT_BUILD_DIR:-build}. Used by demo.sh and test.sh.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${ENVKIT_BUILD_DIR:-$root/build}"
jobs="${ENVKIT_JOBS:-$(nproc)}"
cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release "$@" >/dev/null
ninja -C "$build" -j "$jobs"

# The Python module is used from the build with PYTHONPATH=$build/python, or installed into a venv with pip
# (docs/PYTHON.md, "Set-up"). Only with ENVKIT_PYTHON_PTH=1 does the build write into system site directories: a
# .pth file naming ${build}/python for Debian's interpreter (the one with numpy) and, when another python3 comes
# first on PATH (pyenv), for that one too; nothing is copied. Skipped when the module was not built
# (ENVKIT_SANITIZE, no pybind11) or a site directory is not writable.
if [ "${ENVKIT_PYTHON_PTH:-0}" = 1 ] && [ -d "$build/python/envkit" ]; then
  pth_dirs=()
  [ -x /usr/bin/python3 ] && pth_dirs+=("$(/usr/bin/python3 -c 'import sys; print("/usr/local/lib/python%d.%d/dist-packages" % sys.version_info[:2])')")
  if command -v python3 >/dev/null && [ "$(command -v python3)" != /usr/bin/python3 ]; then
    pth_dirs+=("$(python3 -c 'import site; print(site.getsitepackages()[0])' 2>/dev/null || true)")
  fi
  for d in "${pth_dirs[@]}"; do
    [ -n "$d" ] || continue
    if mkdir -p "$d" 2>/dev/null && [ -w "$d" ]; then
      echo "$build/python" > "$d/envkit-build.pth"
    else
      echo "build: cannot write $d/envkit-build.pth; use PYTHONPATH=$build/python" >&2
    fi
  done
fi
