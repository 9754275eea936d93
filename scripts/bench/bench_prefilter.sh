#!/usr/bin/env bash
# Times envprefilter on two sizes (a usual real-time one and a large one) and its accuracy knob:
#   2048x1024 lat-long -> 256^2 cube, 9 GGX levels + SH + 128^2 DFG LUT   (target <= 1 s wall on 2 cores)
#   8192x4096 lat-long -> 1024^2 cube, 11 GGX levels + SH + LUT           (target <= 10 s)
# and --accuracy 0.1 / 0.2 / 0.3 on the first case. Reports medians of interleaved repeats (wall seconds).
# The usual peer, cmft, is not packaged in Debian 12 (apt-cache search cmft finds nothing), so no
# ratio against it is measured here.
# Usage: scripts/bench/bench_prefilter.sh [--repeats N] [--no-large] [--build DIR]
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
build="${ENVKIT_BUILD_DIR:-$root/build}"
repeats=3
large=1
while [ $# -gt 0 ]; do
  case "$1" in
    --repeats) repeats="$2"; shift 2 ;;
    --no-large) large=0; shift ;;
    --build) build="$2"; shift 2 ;;
    *) echo "bench_prefilter: unknown option $1" >&2; exit 2 ;;
  esac
done
bin="$build/bin/envprefilter"
[ -x "$bin" ] || { echo "bench_prefilter: $bin not built (run scripts/build.sh)" >&2; exit 1; }
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

# A sky gradient with noise and a small very bright sun (the case that makes random-sample prefilters sparkle).
make_sky() {
  local w=$1 h=$2 out=$3
  oiiotool --pattern constant:color=50000,45000,40000 "$((w / 256))x$((h / 128))" 3 \
           --pattern fill:top=0.3,0.5,1.0:bottom=1.0,0.9,0.7 "${w}x${h}" 3 \
           --pattern noise:type=uniform:min=0:max=0.2 "${w}x${h}" 3 --add \
           --paste "+$((w / 3))+$((h / 4))" -d float -o "$out"
}

median() { sort -g | awk '{a[NR]=$1} END {print (NR % 2) ? a[(NR + 1) / 2] : (a[NR / 2] + a[NR / 2 + 1]) / 2}'; }

time_run() {  # prints "wall cpu" seconds of one run (cpu = user + system, all threads)
  local out
  out=$(/usr/bin/time -f "%e %U %S" "$bin" -q --force "$@" 2>&1 >/dev/null | tail -1) ||
    { echo "bench_prefilter: envprefilter $* failed" >&2; exit 1; }
  echo "$out" | awk '{printf "%.3f %.3f\n", $1, $2 + $3}'
}

make_sky 2048 1024 "$work/sky2k.exr"
declare -A times cpu
for ((i = 0; i < repeats; ++i)); do
  for acc in 0.2 0.1 0.3; do
    t=$(time_run "$work/sky2k.exr" --from latlong -o "$work/out.ktx2" --size 256 --accuracy "$acc" \
                 --sh "$work/sh.json" --lut "$work/lut.png")
    times[$acc]+="${t% *} "
    cpu[$acc]+="${t#* } "
  done
  t=$(time_run "$work/sky2k.exr" --from latlong --sh "$work/sh.json")
  times[load]+="${t% *} "
  cpu[load]+="${t#* } "
done
echo "bench_prefilter: $(nproc) cores, load average $(cut -d' ' -f1-3 /proc/loadavg), $repeats repeats"
med() { echo "$1" | tr ' ' '\n' | grep . | median; }
echo "2048x1024 -> 256^2 cube, 9 GGX levels + SH + LUT (medians; wall s, cpu s = user + sys of all threads):"
for acc in 0.1 0.2 0.3; do
  echo "  accuracy $acc: wall $(med "${times[$acc]}"), cpu $(med "${cpu[$acc]}")"
done
echo "  read + SH only: wall $(med "${times[load]}"), cpu $(med "${cpu[load]}")"
if [ "$large" = 1 ]; then
  make_sky 8192 4096 "$work/sky8k.exr"
  t=$(time_run "$work/sky8k.exr" --from latlong -o "$work/out8k.ktx2" --size 1024 --sh "$work/sh.json" \
               --lut "$work/lut.png")
  echo "8192x4096 -> 1024^2 cube, 11 GGX levels + SH + LUT (one run): wall ${t% *} s, cpu ${t#* } s"
fi
if apt-cache search --names-only '^cmft$' 2>/dev/null | grep -q .; then
  echo "cmft: packaged (add it as the peer)"
else
  echo "cmft: not packaged in this Debian (apt-cache search cmft: nothing); no peer ratio"
fi
