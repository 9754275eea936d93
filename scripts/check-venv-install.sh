#!/usr/bin/env bash
# check-venv-install.sh [BUILD_DIR]
# Installs envkit the way a Python user does and runs the pytest suite on that install: a fresh clone of this
# checkout's HEAD (committed files only), a venv made from Debian's python3 with --system-site-packages (numpy,
# setuptools, pybind11 from Debian), `pip install --no-build-isolation .` (pyproject.toml: setuptools driving CMake;
# nothing downloaded), then `import envkit` outside the source tree without PYTHONPATH, and python/tests with that
# interpreter (the CLIs the tests compare against come from BUILD_DIR/bin, default build/). CTest runs it as
# python_venv_install (label long: it builds libenv once more). Exit status: pip's, python's or pytest's.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="$(cd "${1:-$root/build}" && pwd)"
work="$(mktemp -d "${TMPDIR:-/tmp}/envkit-venv.XXXXXX")"
trap 'rm -rf "$work"' EXIT

git clone -q "$root" "$work/src"
/usr/bin/python3 -m venv --system-site-packages "$work/venv"
cmake_args=""
if command -v ccache >/dev/null; then
  # Paths relative to the clone: the next run's clone (another temporary folder) hits the same cache entries.
  cmake_args="-DCMAKE_CXX_COMPILER_LAUNCHER=ccache"
  export CCACHE_BASEDIR="$work/src" CCACHE_NOHASHDIR=1
fi
(cd "$work/src" && CMAKE_ARGS="$cmake_args" ENVKIT_JOBS="${ENVKIT_JOBS:-2}" \
  "$work/venv/bin/pip" install -q --no-build-isolation .)

cd "$work"  # away from the sources: the installed package must stand on its own
env -u PYTHONPATH "$work/venv/bin/python" - <<'PY'
import os, sys
import envkit
assert envkit.__file__.startswith(sys.prefix), "envkit came from %s, not the venv %s" % (envkit.__file__, sys.prefix)
m = envkit.EnvMap.blank(8)
print("installed:", os.path.dirname(envkit.__file__), m)
PY
env -u PYTHONPATH ENVKIT_BIN="$build/bin" ENVKIT_BUILD="$build" \
  "$work/venv/bin/python" -m pytest -q -p no:cacheprovider "$work/src/python/tests"
