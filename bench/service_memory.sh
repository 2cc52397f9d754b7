#!/usr/bin/env bash
# The server's memory under stalled calls (issue 12's probe), for before/after figures.
#   bench/service_memory.sh MLCLUST_BINARY SCENARIO N MIB [serve flags...]
# SCENARIO: specs (N calls sending only a spec that declares MIB MiB) or uploads (N calls
# uploading MIB-1 of MIB MiB, then stalling). Prints the server's VmSize and VmRSS before,
# while the calls wait (after 5 s), and what the calls were answered.
set -euo pipefail
binary=$1 scenario=$2 n=$3 mib=$4
shift 4
port=$((20000 + RANDOM % 20000))
"$binary" serve --listen "127.0.0.1:$port" "$@" 2> /tmp/service_memory_server.log &
server=$!
trap 'kill $server 2>/dev/null; wait $server 2>/dev/null || true' EXIT
sleep 1
memory() { awk '/VmSize|VmRSS/ {printf "%s %d MiB  ", $1, $2/1024}' /proc/$server/status; }
echo "before: $(memory)"
here=$(dirname "$0")
PYTHONPATH=${PYTHONPATH:-build/python} /usr/bin/python3 "$here/service_probe.py" \
  "127.0.0.1:$port" "$scenario" "$n" "$mib" 5 &
probe=$!
sleep 5
echo "waiting: $(memory)"
wait $probe
sleep 2
echo "after the calls end: $(memory)"
"$binary" stats --server "127.0.0.1:$port" 2>/dev/null | grep -E "refused|upload|rejected" | tr '\n' ' ' || true
echo
