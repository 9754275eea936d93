#!/usr/bin/env bash
# bench_render_start.sh [--size WxH] [--repeats N] [--out DIR]
#
# What envrender pays before its first sample on a large map, with the sun split built at load against the split
# stored by envbake (--tables hierarchical,sun). Makes the default probe at WxH (default 8192x4096), bakes both
# table files (time and size), then renders a 96x48 1-spp image of the default scene lit by it N times per file
# (default 3), interleaved, and reports medians of process wall time, envrender's own setup note (split + product
# tables) and peak RSS. Writes DIR/results.md (default out/bench_render_start). Uses build/bin.
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
bin="$root/build/bin"
size=8192x4096
repeats=3
out="$root/out/bench_render_start"
while [ $# -gt 0 ]; do
  case "$1" in
    --size) size="$2"; shift ;;
    --repeats) repeats="$2"; shift ;;
    --out) out="$2"; shift ;;
    -h|--help) sed -n '2,9p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "bench_render_start.sh: unknown argument '$1'" >&2; exit 2 ;;
  esac
  shift
done
for tool in envprobe envbake envrender; do
  [ -x "$bin/$tool" ] || { echo "bench_render_start.sh: $bin/$tool missing (build first)" >&2; exit 1; }
done
mkdir -p "$out"
cd "$out"

"$bin/envprobe" default -o sky.exr --size "$size" >/dev/null
declare -A bake_s bake_mib
for variant in built stored; do
  tables=hierarchical
  [ "$variant" = stored ] && tables=hierarchical,sun
  t0=$(date +%s.%N)
  "$bin/envbake" sky.exr -o "$variant.envtbl" --tables "$tables" -q -f
  bake_s[$variant]=$(echo "$(date +%s.%N) - $t0" | bc -l)
  bake_mib[$variant]=$(( $(stat -c %s "$variant.envtbl") / 1048576 ))
  python3 - "$root/renderer/scenes/default.json" "$variant" <<'EOF'
import json, sys
scene = json.load(open(sys.argv[1]))
scene["environment"] = {"image": "sky.exr", "tables": sys.argv[2] + ".envtbl", "rotation": [180, 0, 0]}
scene["camera"]["resolution"] = [96, 48]
json.dump(scene, open(sys.argv[2] + ".json", "w"), indent=1)
EOF
done

: >runs.txt
for ((r = 0; r < repeats; ++r)); do
  for variant in built stored; do
    log="run_${variant}_$r.log"
    /usr/bin/time -f "wall %e rss %M" "$bin/envrender" --scene "$variant.json" --spp 1 -o "$variant.exr" -f >"$log" 2>&1
    wall=$(grep -o 'wall [0-9.]*' "$log" | cut -d' ' -f2)
    rss=$(grep -o 'rss [0-9]*' "$log" | cut -d' ' -f2)
    setup=$(grep -o 'built in [0-9.e+]* ms' "$log" | grep -o '[0-9.e+]*' | head -1)
    echo "$variant $wall $rss ${setup:-nan}" >>runs.txt
  done
done

median() { sort -g | awk '{v[NR] = $1} END {print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2}'; }
{
  echo "# envrender start on a ${size} map: the sun split built at load vs stored by envbake"
  echo
  echo "$(date -u '+%Y-%m-%d %H:%M UTC'), $(nproc) cores, load average $(cut -d' ' -f1-3 /proc/loadavg), medians of $repeats interleaved runs"
  echo "(\`scripts/bench/bench_render_start.sh --size $size --repeats $repeats\`). The two renders are compared with envdiff below."
  echo
  echo "| tables | envbake s | file MiB | envrender wall s | setup ms (split + product tables) | peak RSS MiB |"
  echo "|---|---:|---:|---:|---:|---:|"
  for variant in built stored; do
    label="--tables hierarchical (split built at load)"
    [ "$variant" = stored ] && label="--tables hierarchical,sun (split stored)"
    wall=$(awk -v v=$variant '$1 == v {print $2}' runs.txt | median)
    rss=$(awk -v v=$variant '$1 == v {print $3}' runs.txt | median)
    setup=$(awk -v v=$variant '$1 == v {print $4}' runs.txt | median)
    printf '| %s | %.2f | %d | %.2f | %.0f | %d |\n' "$label" "${bake_s[$variant]}" "${bake_mib[$variant]}" "$wall" \
      "$setup" "$((rss / 1024))"
  done
  echo
  echo '```'
  "$bin/envdiff" built.exr stored.exr 2>/dev/null | grep -E "^(relmse|max)" || true
  echo '```'
} >results.md
cat results.md
