#!/usr/bin/env bash
# Fails, listing the files, when a C++ file git tracks differs from what clang-format makes of it
# with the checked-in .clang-format. Fix with: clang-format -i FILE...
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
unformatted=()
while IFS= read -r -d '' file; do
  clang-format --dry-run -Werror "$file" >/dev/null 2>&1 || unformatted+=("$file")
done < <(git ls-files -z '*.cpp' '*.h')
if ((${#unformatted[@]} > 0)); then
  echo "check_format: ${#unformatted[@]} files differ from .clang-format: ${unformatted[*]}" >&2
  exit 1
fi
echo "check_format: every tracked C++ file is clang-format clean"
