#!/usr/bin/env bash
# examples/node as an installable npm package (issue 25): its package.json version is
# CMakeLists.txt's project() VERSION; `npm pack` bundles the proto (prepack) and leaves the
# folder as it was (postpack); the tarball and the folder itself install into a fresh project
# with `npm install --offline` (the dependencies from npm's cache, which scripts/node-deps.sh
# filled: no registry), and the installed package, required by name, runs a job against a
# real `mlclust serve`.
#   node_package_test.sh MLCLUST_BINARY DATA_DIR
source "$(dirname "$0")/cli_lib.sh" "$@"
root=$(cd "$(dirname "$0")/../.." && pwd)
command -v npm > /dev/null || fail "npm is not installed (scripts/install-deps.sh installs it)"
bash "$root/scripts/node-deps.sh" || fail "scripts/node-deps.sh could not install examples/node's packages"

version=$(sed -n 's/^project(mlclust VERSION \([0-9.]*\).*/\1/p' "$root/CMakeLists.txt")
[ -n "$version" ] || fail "no project(mlclust VERSION ...) in CMakeLists.txt"
package_version=$(node -p "require('$root/examples/node/package.json').version")
[ "$package_version" = "$version" ] || fail "examples/node/package.json version $package_version, CMakeLists.txt's $version"

(cd "$root/examples/node" && npm pack --pack-destination "$work" --loglevel=error > "$work/pack.out") \
  || fail "npm pack: $(cat "$work/pack.out")"
tarball="$work/mlclust-$version.tgz"
[ -f "$tarball" ] || fail "npm pack wrote no $tarball: $(cat "$work/pack.out")"
tar -tzf "$tarball" > "$work/contents"
grep -qx "package/proto/mlclust/v1/mlclust.proto" "$work/contents" || fail "the tarball lacks the proto"
cmp -s <(tar -xzOf "$tarball" package/proto/mlclust/v1/mlclust.proto) "$root/proto/mlclust/v1/mlclust.proto" \
  || fail "the tarball's proto differs from proto/mlclust/v1/mlclust.proto"
[ ! -e "$root/examples/node/proto" ] || fail "npm pack left examples/node/proto behind"

port=$((20000 + RANDOM % 20000))
start_server "$work/server.log" --listen "127.0.0.1:$port"

# install_and_run NAME SOURCE: a fresh project, `npm install --offline SOURCE`, then a job.
install_and_run() {
  local app="$work/$1"
  mkdir -p "$app"
  (cd "$app" && npm init -y > /dev/null && \
    npm install --offline --no-audit --no-fund --loglevel=error "$2" > "$app/install.out" 2>&1) \
    || fail "$1: npm install --offline $2: $(cat "$app/install.out")"
  (cd "$app" && MLCLUST_SERVER="127.0.0.1:$port" EXPECTED_VERSION="$version" node -e '
    const assert = require("assert");
    const mlclust = require("mlclust");
    assert.strictEqual(mlclust.version, process.env.EXPECTED_VERSION);
    (async () => {
      const client = new mlclust.Client(process.env.MLCLUST_SERVER);
      // A 2 x 2 square of 8 triangles.
      const vertices = [];
      for (let y = 0; y < 3; ++y) for (let x = 0; x < 3; ++x) vertices.push([x, y, 0]);
      const faces = [];
      for (let y = 0; y < 2; ++y) {
        for (let x = 0; x < 2; ++x) {
          const v = 3 * y + x;
          faces.push([v, v + 1, v + 4], [v, v + 4, v + 3]);
        }
      }
      const h = await client.clusterMesh({vertices, faces}, {algo: "hc", energy: "cvd"});
      const one = Array.from(h.labels(1));
      assert.deepStrictEqual(one, new Array(8).fill(one[0]));
      assert.strictEqual(new Set(h.labels(8)).size, 8);
      client.close();
      console.log("ran from", require.resolve("mlclust"));
    })().catch((error) => { console.error(error); process.exit(1); });
  ' > "$app/run.out" 2>&1) || fail "$1: the installed package: $(cat "$app/run.out")"
}
install_and_run from_tarball "$tarball"
grep -q "$work/from_tarball/node_modules/mlclust/mlclust.js" "$work/from_tarball/run.out" \
  || fail "from_tarball: $(cat "$work/from_tarball/run.out")"
install_and_run from_folder "$root/examples/node"
echo "node package: all checks passed"
