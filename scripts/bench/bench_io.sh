#!/usr/bin/env bash
# Image I/O throughput and tool start-up, envkit against OpenImageIO in the same run (BENCHMARKS.md, "Image I/O").
#
#   scripts/bench/bench_io.sh [--build DIR] [--size WxH] [--repeats N] [--baseline BUILD_DIR] [--work DIR] [--startup-only]
#
# Inputs: an WxH (default 8192x4096) float RGB lat-long from envprobe, stored as .exr (zip), .hdr and .pfm.
# For each format, envkit (read_image / write_image) and OIIO (ImageInput / ImageOutput) read and write it,
# interleaved, N times (default 3); the median is reported as MB/s of float RGB pixels (W*H*12 bytes), with the
# ratio envkit/OIIO. OIIO 2.4 cannot write PFM (its writer stores 8-bit data), so that cell is empty.
# Start-up: median wall time of `envinfo --help`, `envinfo small.exr` and a 64x32 -> cube EXR conversion (31 runs,
# timed by Python around each process), and of `oiiotool --help`; with --baseline, the same tools of another build
# (e.g. one that links OIIO), interleaved run by run with envkit's, and the ratio. --startup-only skips the I/O part.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
BUILD=${ENVKIT_BUILD_DIR:-$ROOT/build}
SIZE=8192x4096
REPEATS=3
BASELINE=""
WORK=""
STARTUP_ONLY=0
while [[ $# -gt 0 ]]; do
  case $1 in
    --build) BUILD=$2; shift 2 ;;
    --size) SIZE=$2; shift 2 ;;
    --repeats) REPEATS=$2; shift 2 ;;
    --baseline) BASELINE=$2; shift 2 ;;
    --work) WORK=$2; shift 2 ;;
    --startup-only) STARTUP_ONLY=1; shift ;;
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

if [[ $STARTUP_ONLY == 0 ]]; then
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

fi

# ---- start-up ------------------------------------------------------------------------------------------------
"$BIN/envprobe" default -o "$WORK/small.exr" --size 64x32 >/dev/null
echo
echo "# start-up, $(date -u '+%Y-%m-%d %H:%M UTC'), load average $(cut -d' ' -f1-3 /proc/loadavg) (median of 31 runs, ms)"
python3 - "$BIN" "$BASELINE" "$WORK" <<'PY'
import statistics, subprocess, sys, time
bins = {"envkit": sys.argv[1]}
if sys.argv[2]:
    bins["baseline"] = sys.argv[2] + "/bin"
work = sys.argv[3]
cases = [("envinfo --help", ["envinfo", "--help"]), ("envinfo small.exr", ["envinfo", work + "/small.exr"]),
         ("envconvert small -> cube", ["envconvert", work + "/small.exr", "-o", work + "/cube_small.exr", "--to",
                                       "cube", "--force", "-q"])]
for name, cmd in cases:
    times = {label: [] for label in bins}
    for _ in range(31):
        for label, d in bins.items():  # interleaved: both builds see the same machine
            start = time.perf_counter()
            subprocess.run([d + "/" + cmd[0]] + cmd[1:], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            times[label].append(1e3 * (time.perf_counter() - start))
    m = {label: statistics.median(t) for label, t in times.items()}
    line = "  ".join(f"{label} {v:6.1f}" for label, v in m.items())
    if "baseline" in m:
        line += f"  baseline/envkit {m['baseline'] / m['envkit']:.2f}x"
    print(f"{name:26s} {line}")
PY
ms() {  # median wall milliseconds of 15 runs of a command (bash-timed: includes about 1 ms of its own)
  for i in $(seq 15); do
    s=$(date +%s%N); "$@" >/dev/null 2>&1 || true; e=$(date +%s%N)
    echo $(( (e - s) / 1000000 ))
  done | median
}
command -v oiiotool >/dev/null && printf "%-26s %6s ms\n" "oiiotool --help" "$(ms oiiotool --help)"
echo "# direct dependencies of envinfo: $(ldd "$BIN/envinfo" | wc -l) shared libraries," \
  "OpenImageIO: $(ldd "$BIN/envinfo" | grep -c OpenImageIO || true)"
