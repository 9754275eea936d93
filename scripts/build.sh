#!/usr/bin/env bash
# Configures and builds envkit (Release) into ${ENVKIT_BUILD_DIR:-build}. Used by demo.sh and test.sh.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${ENVKIT_BUILD_DIR:-$root/build}"
jobs="${ENVKIT_JOBS:-$(nproc)}"
cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release "$@" >/dev/null
ninja -C "$build" -j "$jobs"
