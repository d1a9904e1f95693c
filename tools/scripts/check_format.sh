#!/usr/bin/env bash
# The C++ of the repository formatted with its committed .clang-format (ctest clang_format):
# every *.cpp and *.h under core, tools, test, bench and fuzz. Lists the files that differ and exits
# 1; fix them with `tools/scripts/check_format.sh --fix`. Needs clang-format (scripts/setup.sh).
set -euo pipefail
cd "$(dirname "$0")/../.."
if ! command -v clang-format >/dev/null; then
  echo "check_format: clang-format not found (Debian package clang-format; scripts/setup.sh)" >&2
  exit 1
fi
mapfile -t files < <(find core tools test bench fuzz -type f \( -name '*.cpp' -o -name '*.h' \) | sort)
if [ "${1:-}" = --fix ]; then
  clang-format -i "${files[@]}"
  exit 0
fi
unformatted=()
for f in "${files[@]}"; do
  clang-format --dry-run -Werror "$f" >/dev/null 2>&1 || unformatted+=("$f")
done
if ((${#unformatted[@]})); then
  printf 'check_format: not formatted with .clang-format: %s\n' "${unformatted[@]}" >&2
  echo "check_format: ${#unformatted[@]} of ${#files[@]} files; fix: tools/scripts/check_format.sh --fix" >&2
  exit 1
fi
echo "check_format: ${#files[@]} files formatted"
