#!/usr/bin/env bash
# check-format.sh [--changed BASE]
# Checks the tracked C/C++ sources (*.cpp, *.h, *.inl) against .clang-format with clang-format 14.
#   (no argument)   every tracked file: clang-format --dry-run --Werror, which names each file and line out of
#                   format.
#   --changed BASE  only the lines that differ from BASE (a commit, e.g. origin/main; uncommitted changes count):
#                   git clang-format --diff BASE, which prints the diff that would fix them.
# Third-party and generated files are left out (EXCLUDES below). To fix: clang-format -i FILE, or
# git clang-format BASE for the changed lines only.
# Exit 0: formatted; 1: not formatted; 2: usage error or no clang-format 14.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"

base=""
case "${1:-}" in
  "") ;;
  --changed)
    [ $# -eq 2 ] || { echo "check-format.sh: --changed needs one BASE commit" >&2; exit 2; }
    base="$2" ;;
  -h|--help) sed -n '2,10p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
  *) echo "check-format.sh: unknown argument '$1'" >&2; exit 2 ;;
esac

# The project's files only: vendored sources (third_party/, node_modules/) and generated ones are not ours to format.
EXCLUDES=(':(exclude,glob)**/third_party/**' ':(exclude,glob)**/node_modules/**' ':(exclude,glob)**/generated/**')
SOURCES=('*.cpp' '*.h' '*.inl')

clang_format=""
for candidate in clang-format-14 clang-format; do
  if command -v "$candidate" >/dev/null && "$candidate" --version | grep -q 'version 14\.'; then
    clang_format="$(command -v "$candidate")"
    break
  fi
done
[ -n "$clang_format" ] || { echo "check-format.sh: clang-format 14 missing (scripts/install-deps.sh installs it)" >&2; exit 2; }

cd "$root"
if [ -z "$base" ]; then
  mapfile -t files < <(git ls-files -- "${SOURCES[@]}" "${EXCLUDES[@]}")
  [ "${#files[@]}" -gt 0 ] || exit 0
  if ! printf '%s\0' "${files[@]}" | xargs -0 "$clang_format" --dry-run --Werror; then
    echo "check-format.sh: files above are not formatted (.clang-format); clang-format -i FILE fixes them" >&2
    exit 1
  fi
  echo "check-format.sh: ${#files[@]} files formatted"
  exit 0
fi

git rev-parse --verify --quiet "$base^{commit}" >/dev/null || { echo "check-format.sh: --changed: '$base' is not a commit" >&2; exit 2; }
command -v git-clang-format >/dev/null || command -v git-clang-format-14 >/dev/null ||
  { echo "check-format.sh: git-clang-format missing (package clang-format)" >&2; exit 2; }
# git clang-format 14 exits 0 whether or not it finds changes: a diff in its output is the verdict.
diff="$(git clang-format --binary "$clang_format" --diff --extensions cpp,h,inl "$base" -- "${SOURCES[@]}" "${EXCLUDES[@]}")"
if grep -q '^diff --git' <<<"$diff"; then
  printf '%s\n' "$diff"
  echo "check-format.sh: lines changed since $base are not formatted; git clang-format $base fixes them" >&2
  exit 1
fi
echo "check-format.sh: lines changed since $base are formatted"
