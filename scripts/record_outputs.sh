#!/usr/bin/env bash
# Records what envkit's tools and Python module write for a fixed set of calls, as a manifest of SHA-256 sums:
# conversions of the built-in default probe and two blender-data HDRIs to every parameterization and convention,
# bakes of every table method, envrender of the default scene at a fixed seed under every strategy, envprefilter
# outputs and the Python module's results for the same calls. Run it before and after a change that must not
# change behaviour (a refactoring) and compare the manifests:
#   scripts/record_outputs.sh build/bin /tmp/before    # on the old tree
#   scripts/record_outputs.sh build/bin /tmp/after     # on the new tree
#   diff /tmp/before/manifest.txt /tmp/after/manifest.txt
# Usage: record_outputs.sh BIN_DIR OUT_DIR (BIN_DIR holds the tools; the Python module is taken from
# BIN_DIR/../python when it exists). Single-threaded where a tool's output could depend on it; about a minute.
# Every call runs inside OUT_DIR with relative names, so that the paths files record are the same in every run;
# OpenEXR files are compared by their pixels (oiiotool --hash of every subimage), since their metadata holds
# timings, everything else byte for byte.
set -euo pipefail
bin="$(cd "${1:?usage: record_outputs.sh BIN_DIR OUT_DIR}" && pwd)"
out="${2:?usage: record_outputs.sh BIN_DIR OUT_DIR}"
mkdir -p "$out"
out="$(cd "$out" && pwd)"
hdri_dir=/usr/share/blender/datafiles/studiolights/world
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$out"
out=.

"$bin/envprobe" default -o "$out/default.exr" --size 512x256 -q
sources=("$out/default.exr")
for name in courtyard sunrise; do
  [ -f "$hdri_dir/$name.exr" ] && sources+=("$hdri_dir/$name.exr")
done

for src in "${sources[@]}"; do
  stem="$(basename "${src%.exr}")"
  for kind in latlong cube mirrorball angular octahedral paraboloid healpix perspective fisheye; do
    "$bin/envconvert" "$src" -o "$out/${stem}_$kind.exr" --to "$kind" --size 64 --force -q --threads 1
  done
  for convention in openexr hdrshop blender gl threejs directx unity mitsuba pbrt renderman; do
    "$bin/envconvert" "$src" -o "$out/${stem}_cube_$convention.exr" --to cube --convention "$convention" --size 32 \
      --force -q --threads 1
  done
  for filter in nearest bilinear bicubic; do
    "$bin/envconvert" "$src" -o "$out/${stem}_filter_$filter.exr" --to cube --filter "$filter" --size 32 --force -q \
      --threads 1
  done
  "$bin/envbake" "$src" -o "$out/${stem}.envtbl" --tables cdf,alias,hierarchical,compensated,sun \
    --resolution 128x64 --force -q --threads 1
  "$bin/envbake" "$src" -o "$out/${stem}_octahedral.envtbl" --param octahedral --size 64 --force -q --threads 1
  "$bin/envprefilter" "$src" -o "$out/${stem}_ggx.ktx2" --size 16 --sh "$out/${stem}_sh.json" \
    --irradiance "$out/${stem}_irradiance.exr" --irradiance-size 8 --lut "$out/${stem}_lut.exr" --lut-size 16 \
    --force -q --threads 1
done

"$bin/envbake" "$out/default.exr" -o "$out/scene.envtbl" --tables cdf,alias,hierarchical,compensated --force -q
scene="$out/scene.json"
sed -e 's|"environment": {[^}]*}|"environment": {"image": "default.exr", "tables": "scene.envtbl", "rotation": [180, 0, 0], "intensity": 1.0}|' \
  "$root/renderer/scenes/default.json" >"$scene"
for strategy in bsdf light mis mis-compensated product product-mis; do
  "$bin/envrender" --scene "$scene" -o "$out/render_$strategy.exr" --strategy "$strategy" --spp 4 \
    --resolution 96x54 --seed 7 --force -q
done

python_dir="$bin/../python"
if [ -d "$python_dir/envkit" ] && /usr/bin/python3 -c 'import numpy' 2>/dev/null; then
  PYTHONPATH="$python_dir" /usr/bin/python3 - "$out" <<'PY'
import sys, envkit, numpy as np
out = sys.argv[1]
m = envkit.read(out + "/default.exr")
for kind in ("cube", "octahedral", "mirrorball", "healpix"):
    np.save(f"{out}/py_{kind}.npy", np.asarray(m.convert(kind, size=32).data))
np.save(out + "/py_sh.npy", np.asarray(m.sh(order=2)))
np.save(out + "/py_prefilter0.npy", np.asarray(m.prefilter(size=8)[0]))
PY
fi

find . -type f ! -name manifest.txt | sort | while read -r f; do
  case "$f" in
    *.exr) echo "$(oiiotool -a --hash "$f" 2>/dev/null | grep SHA-1 | tr -d ' ' | tr '\n' ' ') $f" ;;
    *) sha256sum "$f" ;;
  esac
done >manifest.txt
echo "record_outputs: $(wc -l <manifest.txt) files in $(pwd)/manifest.txt"
