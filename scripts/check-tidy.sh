#!/usr/bin/env bash
# Runs clang-tidy with the checks of .clang-tidy over our own sources (core/, server/,
# client/, gpu/: the .cc files in BUILD/compile_commands.json; tests, benches and generated
# code are not checked), in parallel, and fails on any warning. Configure first (CMake
# writes compile_commands.json; scripts/build.sh does), since the server's files need the
# generated proto headers.
#   scripts/check-tidy.sh [BUILD]      (default build/; JOBS=N, default nproc)
set -euo pipefail
cd "$(dirname "$0")/.."
build="${1:-build}"
jobs="${JOBS:-$(nproc)}"
command -v clang-tidy > /dev/null || { echo "check-tidy: clang-tidy missing" >&2; exit 1; }
[ -f "$build/compile_commands.json" ] || {
  echo "check-tidy: $build/compile_commands.json missing: configure first (scripts/build.sh)" >&2
  exit 1
}
mapfile -t files < <(/usr/bin/python3 - "$build/compile_commands.json" <<'PY'
import json, os, sys
root = os.getcwd()
for entry in json.load(open(sys.argv[1])):
    path = os.path.relpath(os.path.normpath(os.path.join(entry["directory"], entry["file"])), root)
    if path.split(os.sep)[0] in ("core", "server", "client", "gpu"):
        print(path)
PY
)
[ ${#files[@]} -gt 0 ] || { echo "check-tidy: no sources in $build/compile_commands.json" >&2; exit 1; }
log=$(mktemp)
trap 'rm -f "$log"' EXIT
start=$(date +%s)
# One clang-tidy per file, $jobs at a time; warnings are errors (.clang-tidy says which).
if ! printf '%s\n' "${files[@]}" | sort -u |
    xargs -P "$jobs" -n 1 clang-tidy -p "$build" --quiet > "$log" 2>&1; then
  grep -E "(warning|error):" "$log" >&2 || cat "$log" >&2
  echo "check-tidy: clang-tidy found problems (above)" >&2
  exit 1
fi
echo "check-tidy: ${#files[@]} files clean in $(( $(date +%s) - start )) s ($jobs jobs)"
