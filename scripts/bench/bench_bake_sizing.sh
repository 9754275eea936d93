#!/usr/bin/env bash
# Render efficiency against envbake's importance resolution, with bake time and file size (scripts/bench/bench_bake_sizing.py
# says what and how). Needs build/bin (envbake, envrender, envprobe, envinfo), blender-data, oiiotool, numpy.
#   scripts/bench/bench_bake_sizing.sh [--spp 64] [--ref-spp 1024] [--repeats 3] [--probe-size 8192x4096] [--out DIR]
set -euo pipefail
cd "$(dirname "$0")/../.."
PYTHONPATH="$PWD/scripts:$PWD/build/python${PYTHONPATH:+:$PYTHONPATH}" exec /usr/bin/python3 -m bench.bench_bake_sizing "$@"
