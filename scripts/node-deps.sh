#!/usr/bin/env bash
# Installs the Node example's packages (examples/node: @grpc/grpc-js, @grpc/proto-loader and
# draco3d at the versions its package-lock.json pins) with `npm ci` from the npm registry.
# Nothing to do when node_modules was installed from the current lock file. Needs node and
# npm (scripts/install-deps.sh installs Debian's). Used by .ci/run and by the Node test.
set -euo pipefail
cd "$(dirname "$0")/../examples/node"
if ! command -v node > /dev/null || ! command -v npm > /dev/null; then
  echo "node-deps: node and npm are needed (bash scripts/install-deps.sh)" >&2
  exit 1
fi
exec 9< package-lock.json
flock 9  # one install at a time (CI and parallel tests)
if [ -f node_modules/.package-lock.json ] && [ node_modules/.package-lock.json -nt package-lock.json ]; then
  echo "node-deps: examples/node/node_modules is up to date"
  exit 0
fi
npm ci --no-audit --no-fund --loglevel=error
echo "node-deps: installed examples/node's packages (node $(node --version), npm $(npm --version))"
