#!/usr/bin/env bash
# envconvert against its I/O floor (BENCHMARKS.md, "I/O floor"): for 8k lat-long <-> 1024^2 cube in OpenEXR (zip and
# uncompressed) and Radiance .hdr, the wall time of `envconvert IN -o OUT --to KIND --size N` (area filter, the
# default) and the floor: the time the same library takes to read IN and write OUT's pixels in the same format and
# compression with no resampling (`io_throughput envkit floor`, timed in-process: the floor leaves out the ~12 ms of
# process start-up that envconvert's wall time includes). Median of N interleaved repeats (default 3); the ratio
# envconvert / floor is the figure (targets <= 1.25 for OpenEXR, <= 2 for .hdr).
#
#   scripts/bench/bench_io_floor.sh [--build DIR] [--size WxH] [--face N] [--repeats N] [--work DIR]
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
BUILD=${ENVKIT_BUILD_DIR:-$ROOT/build}
SIZE=8192x4096
FACE=1024
REPEATS=3
WORK=""
while [[ $# -gt 0 ]]; do
  case $1 in
    --build) BUILD=$2; shift 2 ;;
    --size) SIZE=$2; shift 2 ;;
    --face) FACE=$2; shift 2 ;;
    --repeats) REPEATS=$2; shift 2 ;;
    --work) WORK=$2; shift 2 ;;
    -h|--help) sed -n 2,9p "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "bench_io_floor.sh: unknown argument $1" >&2; exit 2 ;;
  esac
done
BIN=$BUILD/bin
for t in envprobe envconvert io_throughput; do
  [[ -x $BIN/$t ]] || { echo "bench_io_floor.sh: $BIN/$t missing (build first: scripts/build.sh)" >&2; exit 1; }
done
if [[ -z $WORK ]]; then WORK=$(mktemp -d /tmp/envkit_io_floor.XXXXXX); trap 'rm -rf "$WORK"' EXIT; fi
mkdir -p "$WORK"

median() { sort -g | awk '{v[NR]=$1} END {print (NR % 2) ? v[(NR+1)/2] : (v[NR/2] + v[NR/2+1]) / 2}'; }
wall() {  # wall seconds of one command
  local s e
  s=$(date +%s%N); "$@" >/dev/null; e=$(date +%s%N)
  awk -v a="$s" -v b="$e" 'BEGIN {printf "%.3f\n", (b - a) / 1e9}'
}

echo "# envconvert vs its I/O floor, $(date -u '+%Y-%m-%d %H:%M UTC'), $(nproc) cores, load average" \
  "$(cut -d' ' -f1-3 /proc/loadavg), $SIZE <-> ${FACE}^2 cube, median of $REPEATS interleaved runs"
[[ -f $WORK/sky.exr ]] || "$BIN/envprobe" default -o "$WORK/sky.exr" --size "$SIZE" >/dev/null
[[ -f $WORK/sky.hdr ]] || "$BIN/envconvert" "$WORK/sky.exr" -o "$WORK/sky.hdr" --to latlong --force -q
[[ -f $WORK/sky_none.exr ]] ||
  "$BIN/envconvert" "$WORK/sky.exr" -o "$WORK/sky_none.exr" --to latlong --compression none --force -q

printf "%-34s %10s %10s %8s\n" "case" "envconvert" "floor" "ratio"
run_case() {  # $1 label, $2 input, $3 output extension, $4 --to kind, $5 --size, $6 compression ("" = default)
  local label=$1 in=$2 ext=$3 kind=$4 size=$5 comp=$6
  local out="$WORK/out_$label.$ext" floor_out="$WORK/floor_$label.$ext"
  local -a comp_opt=()
  [[ -n $comp ]] && comp_opt=(--compression "$comp")
  : >"$WORK/t_tool"; : >"$WORK/t_floor"
  for _ in $(seq "$REPEATS"); do
    wall "$BIN/envconvert" "$in" -o "$out" --to "$kind" --size "$size" "${comp_opt[@]}" --force -q >>"$WORK/t_tool"
    "$BIN/io_throughput" envkit floor "$in" "$out" "$floor_out" $comp | cut -d' ' -f1 >>"$WORK/t_floor"
  done
  local t f
  t=$(median <"$WORK/t_tool"); f=$(median <"$WORK/t_floor")
  printf "%-34s %9.2fs %9.2fs %7.2fx\n" "$label" "$t" "$f" "$(awk -v a="$t" -v b="$f" 'BEGIN {print a / b}')"
}
run_case exr_zip_latlong_to_cube "$WORK/sky.exr" exr cube "$FACE" ""
run_case exr_none_latlong_to_cube "$WORK/sky_none.exr" exr cube "$FACE" none
run_case hdr_latlong_to_cube "$WORK/sky.hdr" hdr cube "$FACE" ""
half=$(( ${SIZE%x*} / 2 ))  # --size of an 8192x4096 lat-long is 4096
run_case exr_zip_cube_to_latlong "$WORK/out_exr_zip_latlong_to_cube.exr" exr latlong "$half" ""
run_case exr_none_cube_to_latlong "$WORK/out_exr_none_latlong_to_cube.exr" exr latlong "$half" none
run_case hdr_cube_to_latlong "$WORK/out_hdr_latlong_to_cube.hdr" hdr latlong "$half" ""
