#!/usr/bin/env bash
# Image I/O throughput and tool start-up, envkit against OpenImageIO in the same run (BENCHMARKS.md, "Image I/O").
#
#   scripts/bench_io.sh [--build DIR] [--size WxH] [--repeats N] [--baseline BUILD_DIR] [--work DIR]
#
# Inputs: an WxH (default 8192x4096) float RGB lat-long from envprobe, stored as .exr (zip), .hdr and .pfm.
# For each format, envkit (read_image / write_image) and OIIO (ImageInput / ImageOutput) read and write it,
# interleaved, N times (default 3); the median is reported as MB/s of float RGB pixels (W*H*12 bytes), with the
# ratio envkit/OIIO. OIIO 2.4 cannot write PFM (its writer stores 8-bit data), so that cell is empty.
# Start-up: median wall time of `envinfo --help`, `envinfo small.exr` and a 64x32 -> cube EXR conversion (15 runs),
# and of `oiiotool --help`; with --baseline, the same tools of another build (e.g. one that links OIIO).
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
BUILD=${ENVKIT_BUILD_DIR:-$ROOT/build}
SIZE=8192x4096
REPEATS=3
BASELINE=""
WORK=""
while [[ $# -gt 0 ]]; do
  case $1 in
    --build) BUILD=$2; shift 2 ;;
    --size) SIZE=$2; shift 2 ;;
    --repeats) REPEATS=$2; shift 2 ;;
    --baseline) BASELINE=$2; shift 2 ;;
    --work) WORK=$2; shift 2 ;;
    -h|--help) sed -n 2,12p "$0"; exit 0 ;;
    *) echo "bench_io.sh: unknown argument $1" >&2; exit 2 ;;
  esac
done
BIN=$BUILD/bin
for t in envprobe envinfo envconvert io_throughput; do
  [[ -x $BIN/$t ]] || { echo "bench_io.sh: $BIN/$t missing (build first: ninja -C $BUILD $t)" >&2; exit 1; }
done
if [[ -z $WORK ]]; then WORK=$(mktemp -d /tmp/envkit_bench_io.XXXXXX); trap 'rm -rf "$WORK"' EXIT; fi
mkdir -p "$WORK"

median() { sort -g | awk '{v[NR]=$1} END {print (NR % 2) ? v[(NR+1)/2] : (v[NR/2] + v[NR/2+1]) / 2}'; }

echo "# envkit image I/O, $(date -u +%Y-%m-%d), $(nproc) cores, $SIZE, median of $REPEATS interleaved runs"
[[ -f $WORK/sky.exr ]] || "$BIN/envprobe" default -o "$WORK/sky.exr" --size "$SIZE" >/dev/null
[[ -f $WORK/sky.hdr ]] || "$BIN/io_throughput" envkit write "$WORK/sky.exr" "$WORK/sky.hdr" >/dev/null
[[ -f $WORK/sky.pfm ]] || "$BIN/io_throughput" envkit write "$WORK/sky.exr" "$WORK/sky.pfm" >/dev/null

printf "%-6s %-6s %12s %12s %8s\n" format op "envkit MB/s" "OIIO MB/s" ratio
for fmt in exr hdr pfm; do
  for op in read write; do
    : >"$WORK/t_envkit" ; : >"$WORK/t_oiio"
    for ((r = 0; r < REPEATS; ++r)); do
      for lib in envkit oiio; do
        [[ $lib == oiio && $op == write && $fmt == pfm ]] && continue
        if [[ $op == read ]]; then
          out=$("$BIN/io_throughput" $lib read "$WORK/sky.$fmt")
        else
          out=$("$BIN/io_throughput" $lib write "$WORK/sky.$fmt" "$WORK/out_$lib.$fmt")
        fi
        echo "$out" | awk '{print $2 / $1}' >>"$WORK/t_$lib"
      done
    done
    e=$(median <"$WORK/t_envkit")
    if [[ -s $WORK/t_oiio ]]; then
      o=$(median <"$WORK/t_oiio")
      printf "%-6s %-6s %12.0f %12.0f %7.2fx\n" $fmt $op "$e" "$o" "$(awk -v a="$e" -v b="$o" 'BEGIN {print a / b}')"
    else
      printf "%-6s %-6s %12.0f %12s %8s\n" $fmt $op "$e" "-" "-"
    fi
  done
done

# ---- start-up ------------------------------------------------------------------------------------------------
"$BIN/envprobe" default -o "$WORK/small.exr" --size 64x32 >/dev/null
ms() {  # median wall milliseconds of 15 runs of a command
  for i in $(seq 15); do
    s=$(date +%s%N); "$@" >/dev/null 2>&1 || true; e=$(date +%s%N)
    echo $(( (e - s) / 1000000 ))
  done | median
}
startup() {  # $1 = label, $2 = bin dir
  printf "%-28s %8s ms\n" "$1 envinfo --help" "$(ms "$2/envinfo" --help)"
  printf "%-28s %8s ms\n" "$1 envinfo small.exr" "$(ms "$2/envinfo" "$WORK/small.exr")"
  printf "%-28s %8s ms\n" "$1 envconvert small -> cube" \
    "$(ms "$2/envconvert" "$WORK/small.exr" -o "$WORK/cube_small.exr" --to cube --force -q)"
}
echo
echo "# start-up (median of 15 runs)"
startup envkit "$BIN"
[[ -n $BASELINE ]] && startup baseline "$BASELINE/bin"
command -v oiiotool >/dev/null && printf "%-28s %8s ms\n" "oiiotool --help" "$(ms oiiotool --help)"
echo "# direct dependencies of envinfo: $(ldd "$BIN/envinfo" | wc -l) shared libraries," \
  "OpenImageIO: $(ldd "$BIN/envinfo" | grep -c OpenImageIO || true)"
