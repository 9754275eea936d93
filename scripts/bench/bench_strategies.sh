#!/usr/bin/env bash
# envrender configurations against each other on bench_cycles' scene and real HDRIs, per region
# (scripts/bench/bench_strategies.py says what and how; --help lists the options). Needs build/bin/envrender,
# blender-data, oiiotool, numpy.
#   scripts/bench/bench_strategies.sh --hdris sunrise,forest --config "1+1=--bsdf-samples 1 --light-samples 1" --config "by lobe="
set -euo pipefail
cd "$(dirname "$0")/../.."
PYTHONPATH="$PWD/scripts:$PWD/build/python${PYTHONPATH:+:$PYTHONPATH}" exec /usr/bin/python3 -m bench.bench_strategies "$@"
