#!/usr/bin/env bash
# Product tables vs power-MIS efficiency on glossy spheres (target: product >= 1.5x power MIS, alpha 0.02 .. 0.3).
# Renders renderer/scenes/glossy.json (sunny default probe) and glossy_overcast.json, a high-spp power-MIS
# reference, then each config below for several seeds; relMSE per sphere, time, efficiency, ratio vs power MIS.
# Output: docs/bench_product.md. Env: BUILD (build dir), SEEDS, REF_SPP, SPP, SCENES, OUT, THREADS.
#   scripts/bench/bench_product_efficiency.sh
#   SEEDS=1 REF_SPP=512 scripts/bench/bench_product_efficiency.sh    (quick look)
set -euo pipefail
cd "$(dirname "$0")/../.."
BUILD=${BUILD:-build}
SEEDS=${SEEDS:-3}
REF_SPP=${REF_SPP:-2048}
SPP=${SPP:-16}
OUT=${OUT:-/tmp/bench_product_efficiency}
THREADS=${THREADS:-0}
SCENES=${SCENES:-"renderer/scenes/glossy.json renderer/scenes/glossy_overcast.json"}
ENVRENDER=$BUILD/renderer/envrender
[ -x "$ENVRENDER" ] || ENVRENDER=$(find "$BUILD" -name envrender -type f -perm -u+x | head -1)
[ -x "$ENVRENDER" ] || { echo "no envrender in $BUILD (cmake --build $BUILD --target envrender)" >&2; exit 1; }
command -v oiiotool >/dev/null || { echo "needs oiiotool" >&2; exit 1; }
scene_args=()
for s in $SCENES; do scene_args+=(--scene "$s"); done
# label|spp|options. The first row is the baseline (power MIS, 1 BSDF + 1 light sample).
if [ -n "${CONFIGS:-}" ]; then
  mapfile -t configs <<<"$CONFIGS"
else
  configs=(
    "mis power 1+1|$SPP|--strategy mis --heuristic power --bsdf-samples 1 --light-samples 1"
    "mis power 1+4|$((SPP / 2))|--strategy mis --heuristic power --bsdf-samples 1 --light-samples 4"
    "mis-compensated 1+1|$SPP|--strategy mis-compensated --bsdf-samples 1 --light-samples 1"
    "product M1|$SPP|--strategy product --light-samples 1"
    "product-mis 1+1|$SPP|--strategy product-mis --bsdf-samples 1 --light-samples 1"
    "product-mis by lobe (default)|$SPP|--strategy product-mis"
  )
fi
config_args=()
for c in "${configs[@]}"; do config_args+=(--config "$c"); done
PYTHONPATH="$PWD/scripts:$PWD/build/python${PYTHONPATH:+:$PYTHONPATH}" /usr/bin/python3 -m bench.bench_product_efficiency --envrender "$ENVRENDER" "${scene_args[@]}" --out "$OUT" \
  --md docs/bench_product.md --ref-spp "$REF_SPP" --seeds "$SEEDS" --threads "$THREADS" "${config_args[@]}"
