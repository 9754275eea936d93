#!/usr/bin/env bash
# Indirect light: envrender --max-depth 2,3,5 vs Blender Cycles at max_bounces 1,2,4 (Filter Glossy 0 and 1), per
# region, against each renderer's unbiased reference, and bias against noise per --regularize value.
# Needs build/bin/envrender, blender + blender-data, oiiotool, numpy, matplotlib. Driver: bench_indirect.py.
#
#   scripts/bench/bench_indirect.sh --quick     reduced run (sunrise, depth 3, 64x36, references 1024 spp)
#   scripts/bench/bench_indirect.sh             full run (sunrise, forest, interior; depths 2, 3, 5; 160x90; 4096 spp)
#   scripts/bench/bench_indirect.sh --depths 3 --spp 64,256 --size 96x54 --ref-spp 2048 --regularize 0,0.5,1
#                                               three HDRIs at depth 3 in about 15 min on 2 loaded cores
#                                               (docs/report/indirect_96x54.md)
#   ... --regularize 0,0.5 --counts default,1+1,1+2,2+2 --repeats 2
#                                               sample counts N+M (--bsdf-samples N --light-samples M) against the
#                                               default, 2 repeats (23 min); time them apart with
#                                               bench_indirect_timing.py (the bench's own times are too noisy)
#   bench_indirect_ab.py --bench <out> old=<build>/bin/envrender new=build/bin/envrender
#                                               two builds (or options) interleaved on a run's scenes and references
#
# Output (default out/bench_indirect/): every EXR, results.json, results.md (tables), bias_noise.png.
set -euo pipefail
cd "$(dirname "$0")/../.."
PYTHONPATH="$PWD/scripts:$PWD/build/python${PYTHONPATH:+:$PYTHONPATH}" exec /usr/bin/python3 -m bench.bench_indirect "$@"
