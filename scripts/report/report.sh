#!/usr/bin/env bash
# report.sh [--quick|--full|--smoke] [--build DIR] [--out DIR] [--no-build] [--repeats N] [--sections LIST] [--keep]
#
# Regenerates the speed-accuracy report: docs/REPORT.md, with its tables (docs/report/*.md), plots
# (docs/report/*.png) and raw numbers (docs/report/*.json). One python file per section in scripts/report/:
#   1 conversion     envconvert filters x output sizes: time vs error against envprobe's exact rasterization as a
#                    renderer sees it (power, GGX-prefiltered levels, irradiance: report/seen.py), sub-texel sun,
#                    envconvert vs exrenvmap (scripts/bench/bench_exrenvmap.sh)
#   2 tables         importance tables at full, 1/2, 1/4, 1/8 resolution: bake time, bytes, render relMSE
#   3 strategies     envrender strategies: relMSE vs time, efficiency vs power-heuristic MIS (6 scenes)
#   4 stratification cdf / alias / hierarchical x random / Sobol at 1..64 samples (envsample irradiance estimates)
#   5 precision      float vs double accumulation, chi-square vs map size (build/bin/bench_precision)
#   6 extremes       sun dynamic range 1e2..1e9 per strategy: relMSE and max pixel error
#   7 prefilter      GGX chains 8^2..256^2 per accuracy against the brute-force sum (build/bin/prefilter_accuracy),
#                    envprefilter wall time per size against the read floor
#   8 indirect       --max-depth 3 per --regularize value: noise at equal spp, bias against the unbiased reference,
#                    total error and efficiency over the unbiased setting
# then report.py assembles docs/REPORT.md with recommendations computed from the numbers.
#
#   --quick     small sizes, few spp, 1 repeat, every section (a few minutes on 2 cores)
#   --full      the real measurement (default; ~30-60 min on 2 cores)
#   --smoke     the smallest case of every section into a temporary directory (< 60 s; for CTest)
#   --build DIR build directory (default build-report; configured Release with Ninja when missing)
#   --no-build  use the binaries in DIR/bin as they are (CTest)
#   --out DIR   tables and plots (default docs/report); REPORT.md goes to DIR/../REPORT.md
#   --repeats N timing repeats (default: full 3, quick 1)
#   --sections  comma list of sections to run (default all; '' = none: only reassemble REPORT.md from --out)
#   --keep      keep the work directory (printed) instead of deleting it
# Exit status: 0 when every section ran (a section may still report a missing feature in its text), 1 otherwise.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
MODE=full
BUILD="$ROOT/build-report"
OUT=""
DO_BUILD=1
REPEATS=""
SECTIONS="conversion,tables,strategies,stratification,precision,extremes,prefilter,indirect"
KEEP=0
PYTHON="${PYTHON:-/usr/bin/python3}"   # Debian's python3 (python3-numpy, python3-matplotlib)

while [[ $# -gt 0 ]]; do
  case "$1" in
    --quick) MODE=quick ;;
    --full) MODE=full ;;
    --smoke) MODE=smoke ;;
    --build) BUILD="$2"; shift ;;
    --out) OUT="$2"; shift ;;
    --no-build) DO_BUILD=0 ;;
    --repeats) REPEATS="$2"; shift ;;
    --sections) SECTIONS="$2"; shift ;;
    --keep) KEEP=1 ;;
    -h|--help) awk 'NR > 1 && !/^#/ { exit } NR > 1 { sub(/^# ?/, ""); print }' "$0"; exit 0 ;;
    *) echo "report.sh: unknown argument '$1'" >&2; exit 2 ;;
  esac
  shift
done

BUILD="$(mkdir -p "$BUILD" && cd "$BUILD" && pwd)"
WORK="$(mktemp -d /tmp/envkit_report.XXXXXX)"
if [[ $MODE == smoke ]]; then
  [[ -n "$OUT" ]] || OUT="$WORK/out/report"
else
  [[ -n "$OUT" ]] || OUT="$ROOT/docs/report"
fi
mkdir -p "$OUT"
OUT="$(cd "$OUT" && pwd)"
cleanup() { if [[ $KEEP == 0 ]]; then rm -rf "$WORK"; else echo "work directory kept: $WORK" >&2; fi; }
trap cleanup EXIT

"$PYTHON" -c 'import numpy, matplotlib' 2>/dev/null || {
  echo "report.sh: $PYTHON lacks numpy/matplotlib (apt install python3-numpy python3-matplotlib)" >&2; exit 1; }
command -v oiiotool >/dev/null || { echo "report.sh: missing oiiotool (apt install openimageio-tools)" >&2; exit 1; }

TARGETS=(envprobe envconvert envdiff envinfo envbake envsample envrender envprefilter _envkit)
if [[ $DO_BUILD == 1 ]]; then
  if [[ ! -f "$BUILD/build.ninja" ]]; then
    cmake -S "$ROOT" -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
  fi
  echo "report.sh: building ${TARGETS[*]} bench_precision prefilter_accuracy in $BUILD" >&2
  cmake --build "$BUILD" -j "${ENVKIT_JOBS:-2}" --target "${TARGETS[@]}" >"$WORK/build.log" 2>&1 || {
    tail -20 "$WORK/build.log" >&2; echo "report.sh: build failed (log above)" >&2; exit 1; }
  # bench_precision (section 5) is optional: without it that section says so and the rest of the report runs.
  cmake --build "$BUILD" -j "${ENVKIT_JOBS:-2}" --target bench_precision >>"$WORK/build.log" 2>&1 ||
    echo "report.sh: could not build bench_precision (section 5 will say so)" >&2
  cmake --build "$BUILD" -j "${ENVKIT_JOBS:-2}" --target prefilter_accuracy >>"$WORK/build.log" 2>&1 ||
    echo "report.sh: could not build prefilter_accuracy (the prefilter section will say so)" >&2
fi
for t in envprobe envconvert envdiff envbake envsample envprefilter; do
  [[ -x "$BUILD/bin/$t" ]] || { echo "report.sh: missing $BUILD/bin/$t" >&2; exit 1; }
done
# Errors as a renderer sees them (report/seen.py) use the Python module built beside the tools.
[[ -f "$BUILD/python/envkit/__init__.py" ]] || { echo "report.sh: missing the Python module in $BUILD/python" >&2; exit 1; }

export REPORT_MODE="$MODE" REPORT_BIN="$BUILD/bin" REPORT_ROOT="$ROOT" REPORT_OUT="$OUT" REPORT_WORK="$WORK"
export REPORT_REPEATS="$REPEATS" PYTHONDONTWRITEBYTECODE=1
# The sections are modules of the package report, which imports the package bench (scripts/bench/common.py).
export PYTHONPATH="$ROOT/scripts:$BUILD/python${PYTHONPATH:+:$PYTHONPATH}"
START=$(date +%s)
FAILED=()
IFS=',' read -r -a SECS <<< "$SECTIONS"
for s in "${SECS[@]}"; do
  t0=$(date +%s)
  echo "report.sh: === $s ($MODE) ===" >&2
  if "$PYTHON" -m "report.$s"; then
    echo "report.sh: $s done in $(( $(date +%s) - t0 )) s" >&2
  else
    echo "report.sh: section $s FAILED after $(( $(date +%s) - t0 )) s" >&2
    FAILED+=("$s")
    printf '## %s\n\nThis section failed to run in the last %s invocation (see the console output of scripts/report/report.sh).\n' \
      "$s" "$MODE" > "$OUT/$s.md"
    rm -f "$OUT/$s.json"
  fi
done
"$PYTHON" -m report.report "$OUT" "$MODE" "$(( $(date +%s) - START ))" "${FAILED[*]:-}"
[[ -s "$(dirname "$OUT")/REPORT.md" ]] || { echo "report.sh: no $(dirname "$OUT")/REPORT.md written" >&2; exit 1; }
echo "report.sh: $MODE report in $(( $(date +%s) - START )) s: $(dirname "$OUT")/REPORT.md" >&2
[[ ${#FAILED[@]} == 0 ]] || { echo "report.sh: failed sections: ${FAILED[*]}" >&2; exit 1; }
