#!/usr/bin/env bash
# The README's first command: install dependencies, build, and run the main job on the built-in default probe
# and scene: generate the probe, describe it, convert it to every parameterization (flux-conserving), bake its
# sampling tables, picture their samples, and render the default scene lit by them.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
"$root/scripts/install-deps.sh" --runtime  # what the main job needs: no test, benchmark or viewer packages
"$root/scripts/build.sh"
bin="${ENVKIT_BUILD_DIR:-$root/build}/bin"
out="${ENVKIT_DEMO_DIR:-$root/out/demo}"
mkdir -p "$out"
echo "== built-in default probe (2048x1024 lat-long) -> $out"
"$bin/envprobe" default -o "$out/default_latlong.exr" --size 2048x1024 --preview "$out/default_latlong.png"
"$bin/envinfo" "$out/default_latlong.exr"
for kind in cube octahedral angular mirrorball paraboloid; do
  "$bin/envconvert" "$out/default_latlong.exr" -o "$out/default_$kind.exr" --to "$kind" --size 512 --force
done
"$bin/envconvert" "$out/default_latlong.exr" -o "$out/default_hcross.exr" --to cube --layout hcross --size 512 --force
"$bin/envconvert" "$out/default_latlong.exr" -o "$out/default_openexr_cube.exr" --to cube --convention openexr --size 512 --force
echo "== power is conserved by the area filter: lat-long vs its cube"
"$bin/envdiff" "$out/default_latlong.exr" "$out/default_cube.exr"
echo "== sampling tables: bake once (cdf, alias, hierarchical, compensated), describe, draw"
"$bin/envbake" "$out/default_latlong.exr" -o "$out/default.envtbl" --tables cdf,alias,hierarchical,compensated --force
"$bin/envinfo" "$out/default.envtbl"
"$bin/envsample" "$out/default.envtbl" -n 4096 --method hierarchical -o "$out/samples_hierarchical.png" --force
echo "== the default scene (spheres of increasing roughness, a diffuse sphere, a ground plane), MIS, lit by the tables"
scene="$out/default_scene.json"
# The shipped default scene with its environment pointed at the files above (paths relative to the scene).
sed -e 's|"environment": {[^}]*}|"environment": {"image": "default_latlong.exr", "tables": "default.envtbl", "rotation": [180, 0, 0], "intensity": 1.0}|' \
  "$root/renderer/scenes/default.json" > "$scene"
"$bin/envrender" --scene "$scene" -o "$out/render.exr" --strategy mis --spp 64
echo "demo outputs in $out (render.png is the preview of render.exr)"
