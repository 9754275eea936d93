#!/usr/bin/env bash
# The README's second command: install dependencies, build, and run every test (CTest). Tests labelled
# "long" run only when ENVKIT_LONG_TESTS=1 (they are listed in the README).
# Then the sanitizer pass (scripts/test-sanitize.sh): the whole suite again built with clang + ASan/UBSan in
# build-asan/, and every libFuzzer target for a short time. ENVKIT_SKIP_SANITIZE=1 skips it (quick local runs);
# the default and CI run it.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
"$root/scripts/install-deps.sh"
"$root/scripts/build.sh"
build="${ENVKIT_BUILD_DIR:-$root/build}"
exclude=(-LE long)
[ "${ENVKIT_LONG_TESTS:-0}" = 1 ] && exclude=()
(cd "$build" && ctest --output-on-failure -j "$(nproc)" --timeout 1200 "${exclude[@]}") || { "$root/scripts/ctest-failures.sh" "$build"; exit 8; }
if [ "${ENVKIT_SKIP_SANITIZE:-0}" != 1 ]; then
  "$root/scripts/test-sanitize.sh"
fi
