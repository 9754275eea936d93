#!/usr/bin/env bash
# Precomputation cost of envrender's light strategies (product tables, auto's pilot, the wavelet, steerable and SH
# seed samplers) per map size and per material kind (scripts/bench/bench_precompute.py says what and how; --help
# lists the options). Needs build/bin/envrender and envprobe, numpy, matplotlib.
#   scripts/bench/bench_precompute.sh       -> docs/report/precompute.md and precompute.png
set -euo pipefail
cd "$(dirname "$0")/../.."
PYTHONPATH="$PWD/scripts:$PWD/build/python${PYTHONPATH:+:$PYTHONPATH}" exec /usr/bin/python3 -m bench.bench_precompute "$@"
