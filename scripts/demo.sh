#!/usr/bin/env bash
# The README's first command: install dependencies, build, and run the main job on the built-in default probe:
# generate it, describe it, convert it to every parameterization (flux-conserving) and write previews.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
"$root/scripts/install-deps.sh"
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
echo "demo outputs in $out"
