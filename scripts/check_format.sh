#!/usr/bin/env bash
# Fails when a tracked C++ file differs from what clang-format (.clang-format: Google style, 120 columns) makes
# of it, and names the files. `bash scripts/check_format.sh --fix` rewrites them in place instead.
# The version matters (formatting changes between releases): this is Debian bookworm's clang-format 14.
set -euo pipefail
cd "$(dirname "$0")/.."
command -v clang-format >/dev/null || { echo "check_format: clang-format is missing (apt-get install clang-format)" >&2; exit 2; }
mapfile -t files < <(git ls-files '*.h' '*.cpp' | grep -v '^fuzz/corpus/\|^fuzz/regressions/')
if [ "${1:-}" = --fix ]; then
  clang-format -i "${files[@]}"
  exit 0
fi
unformatted=()
for f in "${files[@]}"; do
  clang-format --dry-run --Werror "$f" >/dev/null 2>&1 || unformatted+=("$f")
done
if [ ${#unformatted[@]} -gt 0 ]; then
  printf 'check_format: not formatted (run bash scripts/check_format.sh --fix):\n' >&2
  printf '  %s\n' "${unformatted[@]}" >&2
  exit 1
fi
echo "check_format: ${#files[@]} files formatted"
