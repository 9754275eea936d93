#!/usr/bin/env bash
# Installs every Debian 12 package envkit needs to build, test, benchmark and plot.
# Idempotent: packages already present are skipped by apt; safe to run repeatedly.
set -euo pipefail

PACKAGES=(
  build-essential cmake ninja-build pkg-config git
  libopenimageio-dev openimageio-tools      # image I/O (EXR, HDR, PFM, TIFF, PNG, JPEG); maketx for comparisons
  libopenexr-dev libimath-dev openexr       # OpenEXR/Imath; openexr ships exrenvmap for comparisons
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
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ "${#missing[@]}" -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
