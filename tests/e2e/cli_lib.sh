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
