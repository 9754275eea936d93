#!/usr/bin/env bash
# ctest-failures.sh BUILD_DIR: after a failed ctest run, prints the assertion and sanitizer messages of each failed
# test, a few lines per test, so that the end of a long log (all a CI summary shows) says why and not only which.
set -uo pipefail
dir="${1:?usage: ctest-failures.sh BUILD_DIR}/Testing/Temporary"
[ -f "$dir/LastTestsFailed.log" ] || exit 0
echo "== why the failed tests failed (from $dir/LastTest.log)"
while IFS=: read -r _ name; do
  awk -v name="$name" '
    $0 ~ ("^[0-9]+/[0-9]+ Testing: " name "$") { inside = 1; next }
    inside && /^<end of output>/ { exit }
    inside && /\.cpp:[0-9]+: |Expected|Which is|Value of|Actual|[Ee]rror|Sanitizer|SUMMARY|trial|status/ {
      if (shown++ < 8) print "  " name ": " substr($0, 1, 220)
    }' "$dir/LastTest.log"
done < "$dir/LastTestsFailed.log"
