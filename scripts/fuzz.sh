#!/usr/bin/env bash
# fuzz.sh [--seconds N] [--runs N] [--processes P] [--targets "a b"] [--no-build]
#
# Builds the libFuzzer targets (tests/fuzz, clang, ASan + UBSan + libFuzzer) into ${ENVKIT_FUZZ_BUILD_DIR:-build-fuzz},
# replays the seed corpora and every past crash (CTest, label fuzz), then runs every target for N seconds
# (default 60; CI passes 12 through scripts/test-sanitize.sh) on one core each, as many targets side by side as
# there are cores (ENVKIT_JOBS), and prints executions, coverage and findings per target. --runs N runs each target for N executions instead, with no time limit (the long runs of
# BENCHMARKS.md: scripts/fuzz.sh --runs 10000000 --targets "fuzz_codecs fuzz_scene"); --processes P splits that
# budget (or runs for the seconds) across P libFuzzer processes sharing one corpus, one per core (the long runs of
# the slower targets; logs <target>.log.1 .. .P). The growing corpora live in
# <build>/fuzz/corpus/<target> (seeded from tests/fuzz/corpus/<target>); crashes, leaks, timeouts and OOMs are
# written to <build>/fuzz/artifacts/<target>/. A finding: copy the artifact into tests/fuzz/regressions/<target>/
# (it is then replayed by CTest), fix the bug. Slow units (over 10 s, not a failure) are reported, not counted.
# Exit status: 0 when no target found anything, 1 otherwise (every target runs either way), 130 when a signal
# stopped a target's fuzzers short of their budget without a finding. Beside other work: start it
# with setsid nice -n 19, then echo 19 > /proc/PID/autogroup (Linux shares the CPU between sessions before nice counts).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${ENVKIT_FUZZ_BUILD_DIR:-$root/build-fuzz}"
jobs="${ENVKIT_JOBS:-$(nproc)}"
seconds=60
runs=""
targets=""
do_build=1
procs=1
while [ $# -gt 0 ]; do
  case "$1" in
    --seconds) seconds="$2"; shift ;;
    --runs) runs="$2"; shift ;;
    --targets) targets="$2"; shift ;;
    --no-build) do_build=0 ;;
    --processes) procs="$2"; shift ;;
    -h|--help) sed -n '2,16p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "fuzz.sh: unknown argument '$1'" >&2; exit 2 ;;
  esac
  shift
done
case "$procs" in ''|*[!0-9]*|0) echo "fuzz.sh: --processes needs a positive whole number, not '$procs'" >&2; exit 2 ;; esac

export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1${ENVKIT_ASAN_EXTRA:+:$ENVKIT_ASAN_EXTRA}"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1"
export LSAN_OPTIONS="suppressions=$root/tests/fuzz/lsan.supp:print_suppressions=0"  # leaks inside system libraries only
unset OCIO ENVKIT_OCIO_CONFIG

if [ "$do_build" = 1 ]; then
  command -v clang++ >/dev/null || { echo "fuzz.sh: clang++ missing (scripts/install-deps.sh installs it)" >&2; exit 1; }
  t0=$(date +%s)
  CC=clang CXX=clang++ cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1" -DENVKIT_SANITIZE=ON -DENVKIT_FUZZ=ON \
    -DENVKIT_BUILD_TESTS=OFF -DENVKIT_BUILD_BENCHMARKS=OFF -DENVKIT_BUILD_RENDERER=ON >/dev/null
  ninja -C "$build" -j "$jobs" envkit_fuzz_all
  echo "== fuzz build: $(($(date +%s) - t0)) s"
fi
bin="$build/fuzz"
[ -n "$targets" ] || targets="$(cd "$bin" && ls fuzz_* 2>/dev/null | tr '\n' ' ')"
[ -n "$targets" ] || { echo "fuzz.sh: no fuzz targets in $bin" >&2; exit 1; }

echo "== replaying seed corpora and regression inputs (ctest -L fuzz)"
(cd "$build/tests/fuzz" && ctest --output-on-failure -L fuzz -j "$jobs") ||
  { "$root/scripts/ctest-failures.sh" "$build/tests/fuzz"; exit 1; }

work="$build/fuzz/run"
mkdir -p "$work"
# One target's run: its report on stdout, its summary line in $work/<target>.summary; returns 0, 1 (a finding) or
# 130 (stopped by a signal before its budget was spent).
fuzz_target() {
  local t="$1" status=0
  corpus="$build/fuzz/corpus/$t"
  artifacts="$build/fuzz/artifacts/$t"
  mkdir -p "$corpus" "$artifacts"
  seeds=()
  for d in "$root/tests/fuzz/corpus/$t" "$root/tests/fuzz/regressions/$t"; do [ -d "$d" ] && seeds+=("$d"); done
  if [ "$t" = fuzz_tables ]; then  # a valid table file in the current format version
    ENVKIT_FUZZ_WRITE_SEED="$corpus/baked_seed.envtables" "$bin/$t" >/dev/null 2>&1 ||
      echo "fuzz.sh: could not bake a seed table file (EnvTables::bake failed); fuzzing from the corpus only" >&2
  fi
  dict=()
  if [ -f "$root/tests/fuzz/dict/${t#fuzz_}.dict" ]; then dict=(-dict="$root/tests/fuzz/dict/${t#fuzz_}.dict"); fi
  before=$(find "$artifacts" -type f ! -name 'slow-unit-*' | wc -l)
  log="$work/$t.log"
  touch "$log.start"
  if [ -n "$runs" ]; then limit=(-runs="$(((runs + procs - 1) / procs))"); echo "== $t: $runs runs in $procs process(es)"
  else limit=(-max_total_time="$seconds"); echo "== $t: ${seconds} s in $procs process(es)"; fi
  logs=("$log"); [ "$procs" = 1 ] || logs=($(for i in $(seq 1 "$procs"); do echo "$log.$i"; done))
  t_start=$(date +%s)
  # -entropic_scale_per_exec_time: inputs that run longer get less of the mutation budget. A CLI input that
  # rasterizes envprobe's default sky costs far more than one that stops in parsing, and reaches little code the
  # cheap ones do not (the rates with and without: BENCHMARKS.md).
  for attempt in 1 2; do
    pids=()
    for plog in "${logs[@]}"; do
      (cd "$work" && exec "$bin/$t" "$corpus" "${seeds[@]}" "${dict[@]}" "${limit[@]}" -timeout=30 \
         -rss_limit_mb=3072 -max_len=4096 -entropic_scale_per_exec_time=1 -print_final_stats=1 \
         -artifact_prefix="$artifacts/" >"$plog" 2>&1) &
      pids+=($!)
    done
    rc=0
    for p in "${pids[@]}"; do wait "$p" || rc=$?; done
    # LeakSanitizer's stop-the-world tracer itself sometimes dies ("Tracer caught signal 11 ... LeakSanitizer has
    # encountered a fatal error", google/sanitizers#1353): no leak was checked, and the unit it writes replays clean.
    # Then the target runs once more; a second such failure counts as a finding.
    if [ "$attempt" = 1 ] && [ "$rc" != 0 ] && grep -q 'LeakSanitizer has encountered a fatal error' "${logs[@]}" &&
       ! grep -qE 'ERROR: (AddressSanitizer|LeakSanitizer: detected)|runtime error' "${logs[@]}"; then
      echo "   note: LeakSanitizer's tracer failed (a sanitizer flake, not a finding): running $t again"
      find "$artifacts" -type f ! -name 'slow-unit-*' -newer "$log.start" -delete
      continue
    fi
    break
  done
  # Totals over the processes: executions and exec/s add up, coverage is the best any process reached.
  last_stat() { grep -o "$1: *[0-9]*" "$2" | tail -1 | grep -o '[0-9]*$' || true; }
  execs=0; speed=0; cov=0
  for plog in "${logs[@]}"; do
    e=$(last_stat stat::number_of_executed_units "$plog"); execs=$((execs + ${e:-0}))
    v=$(last_stat stat::average_exec_per_sec "$plog"); speed=$((speed + ${v:-0}))
    c=$(last_stat cov "$plog"); [ "${c:-0}" -le "$cov" ] || cov=$c
  done
  # libFuzzer writes slow-unit-* for any unit over 10 s of wall time without failing: on a shared 2-core machine
  # under ASan that measures the machine's load as much as the code, so they are reported and kept, not counted.
  # A unit over -timeout (30 s) is a timeout-* artifact and a finding.
  slow=$(find "$artifacts" -name 'slow-unit-*' -newer "$log.start" | wc -l)
  [ "$slow" = 0 ] || echo "   note: $slow slow unit(s) (> 10 s) in $artifacts (not counted as findings)"
  after=$(find "$artifacts" -type f ! -name 'slow-unit-*' | wc -l)
  found=$((after - before))
  if [ "$found" -gt 0 ] || { [ "$rc" != 0 ] && [ "$rc" != 72 ]; }; then
    status=1
    echo "   FINDING in $t (exit $rc): $(ls -t "$artifacts" | grep -v '^slow-unit-' | head -1 || true)"
    cat "${logs[@]}" | grep -E 'ERROR: |FINDING|runtime error|SUMMARY' | head -5 | sed 's/^/   /' || true
  elif [ "$rc" = 72 ]; then
    # 72 is libFuzzer's exit status when a signal (SIGINT, SIGTERM) stops it: a run cut short, not a finding. The
    # figures below are those of the executions done; the exit status says the budget was not spent.
    status=130
    echo "   interrupted: $t stopped before its budget was spent"
  fi
  line="$(printf '%-22s %10s execs %7s exec/s %6s s  cov %6s  corpus %5s  findings %s' "$t" "${execs:-?}" \
           "${speed:-?}" "$(($(date +%s) - t_start))" "${cov:-?}" "$(ls "$corpus" | wc -l)" "$found")"
  echo "   $line"
  echo "$line" >"$work/$t.summary"
  return "$status"
}

status=0
summary=()
# Targets run side by side, as many as the cores hold beside their --processes each: the fuzzing per target is the
# same, the wall time shorter. Each target's report is printed whole when it ends.
parallel=$((jobs / procs)); [ "$parallel" -ge 1 ] || parallel=1
running=()
finish_oldest() {
  local t="${running[0]}" rc=0
  wait "${pids_of[$t]}" || rc=$?
  cat "$work/$t.out"
  summary+=("$(cat "$work/$t.summary" 2>/dev/null || echo "$t: no summary (see $work/$t.out)")")
  if [ "$rc" = 1 ] || { [ "$rc" != 0 ] && [ "$rc" != 130 ]; }; then status=1
  elif [ "$rc" = 130 ] && [ "$status" = 0 ]; then status=130; fi
  running=("${running[@]:1}")
}
declare -A pids_of
for t in $targets; do
  [ "${#running[@]}" -lt "$parallel" ] || finish_oldest
  fuzz_target "$t" >"$work/$t.out" 2>&1 &
  pids_of[$t]=$!
  running+=("$t")
done
while [ "${#running[@]}" -gt 0 ]; do finish_oldest; done
budget="${seconds} s"; [ -z "$runs" ] || budget="$runs runs"
echo "== fuzz summary ($budget per target; logs in $work)"
printf '%s\n' "${summary[@]}"
exit "$status"
