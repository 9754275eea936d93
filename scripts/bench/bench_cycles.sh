#!/usr/bin/env bash
# envrender vs Blender Cycles on real HDRIs of blender-data: efficiency (1 / (relMSE x seconds)) per region at
# several spp, each renderer against its own converged reference, and agreement of the two references.
# Needs build/renderer/envrender (ninja -C build envrender), blender + blender-data, oiiotool, numpy, matplotlib.
#
#   scripts/bench/bench_cycles.sh                      full run: sunrise, forest, interior; 16/64/256 spp; 160x90
#   scripts/bench/bench_cycles.sh --quick              debug run (sunrise, 64x36, 4/16 spp, references 256 spp)
#   scripts/bench/bench_cycles.sh --scene mesh         the OBJ mesh scene (a diffuse torus, a GGX torus knot) instead
#   scripts/bench/bench_cycles.sh --hdris sunset,courtyard,interior --spp 16,64,256 --size 200x112 --ref-spp 4096 --repeats 3
#   scripts/bench/bench_cycles.sh --hdris forest --crop 49,31,77,59 --ref-spp 65536 --spp 256
#                                                one window (here the GGX 0.05 sphere) in both renderers: references
#                                                long enough to see whether they converge to the same image
#
# Output (default out/bench_cycles/): per HDRI the envrender scene, every EXR, refs_<hdri>.png (the two
# references and their relative difference), results.json (all figures), results.md (tables), efficiency.png.
set -euo pipefail
cd "$(dirname "$0")/../.."
PYTHONPATH="$PWD/scripts:$PWD/build/python${PYTHONPATH:+:$PYTHONPATH}" exec /usr/bin/python3 -m bench.bench_cycles "$@"
