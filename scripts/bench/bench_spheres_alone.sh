#!/usr/bin/env bash
# Glossy spheres under real HDRIs, each rendered and timed alone: envrender's default against power MIS
# (scripts/bench/bench_spheres_alone.py says what and how; --help lists the options). Needs build/bin/envrender,
# blender-data, oiiotool, numpy.
#   scripts/bench/bench_spheres_alone.sh --hdris sunrise --seeds 3 --ref-spp 1024   (a quick look)
set -euo pipefail
cd "$(dirname "$0")/../.."
PYTHONPATH="$PWD/scripts:$PWD/build/python${PYTHONPATH:+:$PYTHONPATH}" exec /usr/bin/python3 -m bench.bench_spheres_alone "$@"
