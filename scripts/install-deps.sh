#!/usr/bin/env bash
# install-deps.sh [--runtime]
# Installs the Debian 12 packages envkit needs. By default (scripts/test.sh) every package needed to build, test,
# benchmark and plot. --runtime (scripts/demo.sh): only what building and running the tools, envrender, envprobe
# and the Python module needs; CMake then builds no tests (GoogleTest absent).
# Idempotent: packages already present are skipped by apt; safe to run repeatedly.
set -euo pipefail

mode=full
case "${1:-}" in
  "") ;;
  --runtime) mode=runtime ;;
  -h|--help) sed -n '2,6p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
  *) echo "install-deps.sh: unknown argument '$1' (expected --runtime or nothing)" >&2; exit 2 ;;
esac

# Build and run: libenv, the tools, envprobe, envrender and the Python module.
RUNTIME_PACKAGES=(
  build-essential cmake ninja-build pkg-config git
  libopenimageio-dev                        # image I/O (TIFF, JPEG, ...) in the OIIO module
  libopenexr-dev libimath-dev               # OpenEXR/Imath
  libpng-dev                                # PNG without loading OIIO's module (LUTs, previews, LDR maps)
  libopencolorio-dev                        # colour-space conversion
  libembree-dev                             # Embree 3 BVH for envrender
  libcli11-dev                              # command-line parsing
  libtbb-dev                                # oneTBB parallelism
  nlohmann-json3-dev                        # JSON scene files and metadata
  libtinyobjloader-dev                      # OBJ meshes
  libxxhash-dev                             # XXH3 checksums and content hashes of table files
  libhealpix-cxx-dev                        # HEALPix pixel geometry (Healpix_Base: xyf2loc, vec2pix, RING/NESTED)
  # Python module envkit (python/, docs/PYTHON.md): pybind11 bindings and the dask batch runner
  python3 python3-numpy                     # Debian's interpreter and the arrays the module hands out
  python3-dev python3-pybind11 pybind11-dev  # headers of Debian's python3 and pybind11 (CMake config)
  python3-distributed                       # python3 -m envkit.batch on a dask.distributed cluster
  python3-setuptools python3-wheel python3-venv  # pip install --no-build-isolation . into a venv (pyproject.toml)
)

# Tests, benchmarks, comparisons with peers and plots (scripts/test.sh, the bench and report scripts).
TEST_PACKAGES=(
  libgtest-dev libgmock-dev googletest      # unit tests
  libbenchmark-dev                          # micro-benchmarks
  clang libclang-rt-14-dev                  # sanitizer and fuzzer builds
  clang-format                              # scripts/check-format.sh (clang-format 14 on Debian 12)
  valgrind                                  # callgrind instruction counts in benchmarks
  openimageio-tools                         # maketx and oiiotool for comparisons
  openexr                                   # exrenvmap for comparisons
  python3-matplotlib                        # report plots
  python3-pytest python3-hypothesis python3-scipy  # python/tests, run by CTest
  python3-healpy                            # independent HEALPix implementation the tests compare against
  # envprefilter (real-time IBL outputs)
  nodejs                                    # runs ktx-parse and parse-dds, the independent KTX2 and DDS readers (brings npm)
  # The three.js viewer (web/) and its test: Debian's Chromium renders the page headless, WebGL on SwiftShader
  # (bundled with the package; no GPU, no display server, no browser download)
  chromium
  blender blender-data                      # Cycles, the renderer peer of scripts/bench/bench_cycles.sh; blender-data's HDRIs
)

PACKAGES=("${RUNTIME_PACKAGES[@]}")
[ "$mode" = full ] && PACKAGES+=("${TEST_PACKAGES[@]}")

# npm packages, each folder pinned by its package-lock.json: tests/js (ktx-parse and parse-dds, the independent KTX2
# and DDS readers) and web/ (three, the viewer's renderer). Skipped where the packages are already installed, and
# in --runtime mode (only the tests and the viewer use them).
install_js_packages() {
  local root dir package entry missing_package
  root="$(cd "$(dirname "$0")/.." && pwd)"
  [ "$mode" = full ] || return 0
  command -v npm >/dev/null 2>&1 || return 0
  for entry in "tests/js:ktx-parse parse-dds" "web:three"; do
    dir="$root/${entry%%:*}"
    missing_package=0
    for package in ${entry#*:}; do
      [ -d "$dir/node_modules/$package" ] || missing_package=1
    done
    if [ -f "$dir/package-lock.json" ] && [ "$missing_package" = 1 ]; then
      echo "install-deps: npm ci in ${entry%%:*}"
      (cd "$dir" && npm ci --no-audit --no-fund)
    fi
  done
}

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ "${#missing[@]}" -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} packages ($mode set) present"
  install_js_packages
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
install_js_packages
