#!/usr/bin/env bash
# The README's second command: install dependencies, build, and run every test (CTest). Tests labelled
# "long" run only when ENVKIT_LONG_TESTS=1 (they are listed in the README).
# Then the sanitizer pass (scripts/test-sanitize.sh): the whole suite again built with clang + ASan/UBSan in
# build-asan/, and every libFuzzer target for a short time. ENVKIT_SKIP_SANITIZE=1 skips it (quick local runs);
# the default and CI run it.
# Before the tests, every tracked C/C++ file is checked against .clang-format (scripts/check-format.sh); the tests
# run either way, and a formatting failure fails the command at the end (exit 9).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
"$root/scripts/install-deps.sh"
format_ok=1
"$root/scripts/check-format.sh" || format_ok=0
"$root/scripts/build.sh"
build="${ENVKIT_BUILD_DIR:-$root/build}"
exclude=(-LE long)
[ "${ENVKIT_LONG_TESTS:-0}" = 1 ] && exclude=()
(cd "$build" && ctest --output-on-failure -j "$(nproc)" --timeout 1200 "${exclude[@]}") || { "$root/scripts/ctest-failures.sh" "$build"; exit 8; }
if [ "${ENVKIT_SKIP_SANITIZE:-0}" != 1 ]; then
  "$root/scripts/test-sanitize.sh"
fi
if [ "$format_ok" != 1 ]; then
  echo "test.sh: the tests passed, but C/C++ files are not formatted (scripts/check-format.sh, above)" >&2
  exit 9
fi
