# What the CLI test scripts share; sourced as
#   source "$(dirname "$0")/cli_lib.sh" "$@"      (arguments: MLCLUST_BINARY DATA_DIR)
# Sets mlclust, data and work (a scratch folder removed on exit, with the server whose pid
# is in server_pid, if any), and defines fail MESSAGE (prints it and exits 1).
set -euo pipefail
mlclust=$1
data=$2
work=$(mktemp -d)
server_pid=""
cleanup() {
  [ -n "$server_pid" ] && kill "$server_pid" 2>/dev/null && wait "$server_pid" 2>/dev/null
  rm -rf "$work"
}
trap cleanup EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
# start_server LOG ARGS...: `mlclust serve ARGS...` in the background, its stderr in LOG and
# its pid in server_pid (stopped on exit); waits up to 10 s for "serving", else fails.
start_server() {
  local log=$1
  shift
  "$mlclust" serve "$@" 2> "$log" &
  server_pid=$!
  for _ in $(seq 100); do
    grep -q "serving" "$log" 2>/dev/null && return 0
    sleep 0.1
  done
  fail "server did not start: $(cat "$log")"
}
