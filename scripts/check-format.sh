#!/usr/bin/env bash
# Fails when a C++ file differs from what .clang-format makes of it (generated code under
# build/ is not tracked, so it is not checked). Fix with:
#   git ls-files '*.cc' '*.h' | xargs clang-format -i
set -euo pipefail
cd "$(dirname "$0")/.."
command -v clang-format > /dev/null || { echo "check-format: clang-format missing" >&2; exit 1; }
off=$(git ls-files '*.cc' '*.h' | while read -r f; do
  clang-format --dry-run -Werror "$f" > /dev/null 2>&1 || echo "$f"
done)
if [ -n "$off" ]; then
  echo "check-format: not formatted by .clang-format:" >&2
  echo "$off" >&2
  exit 1
fi
echo "check-format: $(git ls-files '*.cc' '*.h' | wc -l) files formatted"
