#!/usr/bin/env bash
# envrender's default (auto, the pilot per material) against power MIS and product-mis, each sphere alone
# (scripts/bench/bench_default_pilot.py says what and how; --help lists the options). Needs build/bin/envrender,
# blender-data, oiiotool, numpy.
#   scripts/bench/bench_default_pilot.sh --hdris sunrise --scenes spheres --seeds 1   (a quick look)
set -euo pipefail
cd "$(dirname "$0")/../.."
PYTHONPATH="$PWD/scripts:$PWD/build/python${PYTHONPATH:+:$PYTHONPATH}" exec /usr/bin/python3 -m bench.bench_default_pilot "$@"
