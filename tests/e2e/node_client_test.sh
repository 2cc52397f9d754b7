#!/usr/bin/env bash
# The Node example client (examples/node) against a real `mlclust serve`: its sequential
# upload gives the C++ CLI's labels; a draco3d edgebreaker payload with the per-face id
# attribute maps labels back exactly; without it Accepted says the decoded order; a bad
# request is INVALID_ARGUMENT with the message; a level over 4 MiB reaches a client at
# gRPC's default limits. Never skipped: scripts/install-deps.sh installs node and npm,
# scripts/node-deps.sh the example's packages (npm ci).
#   node_client_test.sh MLCLUST_BINARY DATA_DIR
source "$(dirname "$0")/cli_lib.sh" "$@"
root=$(cd "$(dirname "$0")/../.." && pwd)
command -v node > /dev/null || fail "node is not installed (scripts/install-deps.sh installs it)"
bash "$root/scripts/node-deps.sh" || fail "scripts/node-deps.sh could not install examples/node's packages"

port=$((20000 + RANDOM % 20000))
start_server "$work/server.log" --listen "127.0.0.1:$port"

# The C++ CLI's labels for the job the Node client repeats (ml, cvd, seed 1; level 50).
"$mlclust" mesh "$data/fandisk.off" --server "127.0.0.1:$port" --algo ml --clusters 50 \
  --labels "$work/cli_ml50.labels" --quiet > /dev/null || fail "the C++ CLI failed"

MLCLUST_SERVER="127.0.0.1:$port" MLCLUST_MESH="$data/fandisk.off" \
  CLI_ML_LABELS="$work/cli_ml50.labels" node "$(dirname "$0")/node_client_test.js" \
  || fail "node_client_test.js"

# The example's CLI, as the README shows it.
node "$root/examples/node/cluster.js" "$data/fandisk.off" --server "127.0.0.1:$port" \
  --algo ml -k 50 --labels "$work/node_ml50.labels" --quiet > "$work/cluster.out" \
  || fail "examples/node/cluster.js failed"
cmp -s "$work/cli_ml50.labels" "$work/node_ml50.labels" || fail "cluster.js --labels differ from the C++ CLI's"
grep -q "^12946 levels, 12946 -> 1 clusters" "$work/cluster.out" || fail "cluster.js: $(cat "$work/cluster.out")"
if node "$root/examples/node/cluster.js" "$data/fandisk.off" --server "127.0.0.1:$port" \
  --algo ml --option guard=sideways --quiet 2> "$work/bad.err"; then
  fail "cluster.js accepted a bad option value"
fi
grep -q "INVALID_ARGUMENT: .*guard" "$work/bad.err" || fail "cluster.js error: $(cat "$work/bad.err")"
echo "node client: all checks passed"
