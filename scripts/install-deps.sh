#!/usr/bin/env bash
# Installs every Debian 12 package envkit needs to build, test, benchmark and plot.
# Idempotent: packages already present are skipped by apt; safe to run repeatedly.
set -euo pipefail

PACKAGES=(
  build-essential cmake ninja-build pkg-config git
  libopenimageio-dev openimageio-tools      # image I/O (EXR, HDR, PFM, TIFF, PNG, JPEG); maketx for comparisons
  libopenexr-dev libimath-dev openexr       # OpenEXR/Imath; openexr ships exrenvmap for comparisons
  libpng-dev                                # PNG without loading OIIO's module (LUTs, previews, LDR maps)
  libopencolorio-dev                        # colour-space conversion
  libembree-dev                             # Embree 3 BVH for envrender
  libcli11-dev                              # command-line parsing
  libtbb-dev                                # oneTBB parallelism
  libgtest-dev libgmock-dev googletest      # unit tests
  libbenchmark-dev                          # micro-benchmarks
  nlohmann-json3-dev                        # JSON scene files and metadata
  libtinyobjloader-dev                      # OBJ meshes
  libxxhash-dev                             # XXH3 checksums and content hashes of table files
  python3 python3-matplotlib python3-numpy  # report plots
  clang libclang-rt-14-dev                  # sanitizer and fuzzer builds
  valgrind                                  # callgrind instruction counts in benchmarks
  # Python module envkit (python/, docs/PYTHON.md): pybind11 bindings, their tests, the dask batch runner
  python3-dev python3-pybind11 pybind11-dev  # headers of Debian's python3 and pybind11 (CMake config)
  python3-pytest                            # python/tests, run by CTest
  python3-distributed                       # python3 -m envkit.batch on a dask.distributed cluster
  # HEALPix parameterization
  libhealpix-cxx-dev                        # HEALPix pixel geometry (Healpix_Base: xyf2loc, vec2pix, RING/NESTED)
  python3-healpy                            # independent HEALPix implementation the tests compare against
  # envprefilter (real-time IBL outputs)
  nodejs                                    # runs ktx-parse and parse-dds, the independent KTX2 and DDS readers (brings npm)
  # The three.js viewer (web/) and its test: Debian's Chromium renders the page headless, WebGL on SwiftShader
  # (bundled with the package; no GPU, no display server, no browser download)
  chromium
  blender blender-data                      # Cycles, the renderer peer of scripts/bench_cycles.sh; blender-data's HDRIs
)

# npm packages, each folder pinned by its package-lock.json: tests/js (ktx-parse and parse-dds, the independent KTX2
# and DDS readers) and web/ (three, the viewer's renderer). Skipped where the packages are already installed.
install_js_packages() {
  local root dir package entry missing_package
  root="$(cd "$(dirname "$0")/.." && pwd)"
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
  echo "install-deps: all ${#PACKAGES[@]} packages present"
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
