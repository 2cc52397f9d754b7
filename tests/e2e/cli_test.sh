#!/usr/bin/env bash
# The CLI end to end: the embedded server and a separate `mlclust serve` give the same
# levels; the labels' energy, recomputed from the mesh file alone, equals the reported
# one; bad input gets a message and a non-zero exit while the server keeps serving; points
# with --auto-k bic recover the number of blobs.
#   cli_test.sh MLCLUST_BINARY DATA_DIR
source "$(dirname "$0")/cli_lib.sh" "$@"

# Embedded.
"$mlclust" mesh "$data/fandisk.off" --algo hc --clusters 100 --labels "$work/embedded.labels" \
  --levels-csv "$work/embedded.csv" --ply "$work/embedded.ply" --quiet > "$work/embedded.out"
[ "$(wc -l < "$work/embedded.labels")" -eq 12946 ] || fail "labels: not one line per face"
[ "$(sort -un "$work/embedded.labels" | wc -l)" -eq 100 ] || fail "labels: not 100 clusters"
[ "$(head -1 "$work/embedded.csv")" = "clusters,energy" ] || fail "csv header"
[ "$(wc -l < "$work/embedded.csv")" -eq 12947 ] || fail "csv: not one row per level"
reported=$(grep '^100,' "$work/embedded.csv" | cut -d, -f2)
recomputed=$("$mlclust" energy "$data/fandisk.off" --labels "$work/embedded.labels")
/usr/bin/env awk -v a="$reported" -v b="$recomputed" 'BEGIN {
  d = a - b; if (d < 0) d = -d; exit !(d <= 1e-9 * b) }' \
  || fail "reported energy $reported != recomputed $recomputed"
head -c 3 "$work/embedded.ply" | grep -q ply || fail "ply header"

# A separate server on a free port.
port=$((20000 + RANDOM % 20000))
start_server "$work/server.log" --listen "127.0.0.1:$port"
grep -q "GL" "$work/server.log" || fail "server did not log its GL renderer"

"$mlclust" mesh "$data/fandisk.off" --server "127.0.0.1:$port" --algo hc --clusters 100 \
  --labels "$work/remote.labels" --levels-csv "$work/remote.csv" --quiet > "$work/remote.out"
cmp -s "$work/embedded.labels" "$work/remote.labels" || fail "remote labels differ from embedded"
cmp -s "$work/embedded.csv" "$work/remote.csv" || fail "remote levels differ from embedded"

# Bad input: a non-manifold edge (three faces on edge 0-1), as an OBJ file.
printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n' > "$work/fin.obj"
if "$mlclust" mesh "$work/fin.obj" --server "127.0.0.1:$port" --quiet 2> "$work/bad.err"; then
  fail "a non-manifold mesh was accepted"
fi
grep -q "non-manifold edge" "$work/bad.err" || fail "no message for the bad mesh: $(cat "$work/bad.err")"
# Random bytes as a .drc file.
head -c 5000 /dev/urandom > "$work/garbage.drc"
if "$mlclust" mesh "$work/garbage.drc" --server "127.0.0.1:$port" --quiet 2> "$work/garbage.err"; then
  fail "random bytes were accepted"
fi
[ -s "$work/garbage.err" ] || fail "no message for random bytes"
# The server is still up and serving.
"$mlclust" mesh "$data/elephant.off" --server "127.0.0.1:$port" --clusters 10 --quiet \
  > /dev/null || fail "the server stopped serving after bad input"
"$mlclust" stats --server "127.0.0.1:$port" | grep -q "jobs_succeeded: 2" || fail "stats"
# VSA is served (the planar energy is its default).
"$mlclust" mesh "$data/fandisk.off" --server "127.0.0.1:$port" --algo vsa --clusters 20 \
  --labels "$work/vsa.labels" --quiet > "$work/vsa.out" || fail "vsa failed"
[ "$(sort -un "$work/vsa.labels" | wc -l)" -eq 20 ] || fail "vsa: not 20 clusters"
if "$mlclust" mesh "$data/fandisk.off" --algo vsa --energy cvd --clusters 20 --quiet \
  2> "$work/vsa.err"; then fail "vsa with cvd accepted"; fi
grep -q "available: planar" "$work/vsa.err" || fail "vsa energy: $(cat "$work/vsa.err")"
# Cluster counts above the face count, or above 32 bits, are refused (not truncated).
for k in 12947 4294967396; do
  if "$mlclust" mesh "$data/fandisk.off" --algo hc --clusters "$k" --quiet 2> "$work/k.err"; then
    fail "--clusters $k accepted"
  fi
  grep -q "clusters" "$work/k.err" || fail "--clusters $k: $(cat "$work/k.err")"
done
# Unknown options and missing files get a message and exit 2 / non-zero.
if "$mlclust" mesh "$data/fandisk.off" --bogus 1 2> "$work/opt.err"; then fail "--bogus accepted"; fi
grep -q "unknown option --bogus" "$work/opt.err" || fail "no message for --bogus"
if "$mlclust" mesh "$work/missing.off" --quiet 2> /dev/null; then fail "missing file accepted"; fi
# The parser (CLI11): a bad flag is named, with exit 2.
expect_bad_flag() {  # expect_bad_flag TEXT ARGS...: exit 2 and TEXT on stderr
  local text=$1 code=0
  shift
  "$mlclust" "$@" > /dev/null 2> "$work/flag.err" || code=$?
  [ "$code" -eq 2 ] || fail "$*: exit $code, not 2: $(cat "$work/flag.err")"
  grep -q -- "$text" "$work/flag.err" || fail "$*: no '$text' in: $(cat "$work/flag.err")"
}
expect_bad_flag "unknown option --bogus" mesh "$data/fandisk.off" --bogus 1
expect_bad_flag "unknown option --bogus" mesh "$data/fandisk.off" --bogus=1
expect_bad_flag "unknown option -x" points "$work/missing.csv" -x
expect_bad_flag "unknown option --kmax" mesh "$data/fandisk.off" --kmax 3   # a points option
expect_bad_flag "unknown option --listen" stats --server 127.0.0.1:1 --listen 1
expect_bad_flag "deadline needs a value" jobs --server 127.0.0.1:1 --deadline
expect_bad_flag "clusters needs a value" mesh "$data/fandisk.off" -k
expect_bad_flag "quiet" mesh "$data/fandisk.off" --quiet=yes
expect_bad_flag "labels needs a value" mesh "$data/fandisk.off" -k 5 --labels= --ply "$work/x.ply"
expect_bad_flag "unknown option --bogus" serve --bogus 1
expect_bad_flag "serve: unexpected argument 'extra'" serve extra
expect_bad_flag "no command 'bogus'" help bogus
# The embedded server creates a GL context only where the job can use one (--device gpu,
# --preview, or auto with a GPU device node): the same labels either way, and gpu still
# reports the renderer.
"$mlclust" mesh "$data/elephant.off" --algo hc -k 20 -o "$work/auto.labels" -q --json \
  > "$work/auto.json" || fail "--device auto"
"$mlclust" mesh "$data/elephant.off" --algo hc -k 20 -o "$work/cpu.labels" -q --device cpu \
  > /dev/null || fail "--device cpu"
cmp -s "$work/auto.labels" "$work/cpu.labels" || fail "--device auto and cpu differ"
"$mlclust" mesh "$data/elephant.off" --algo hc -k 20 -q --device gpu --json > "$work/gpu.json" \
  || fail "--device gpu"
/usr/bin/python3 -c '
import json, sys
assert json.load(open(sys.argv[1]))["device"] != "cpu", "--device gpu ran without GL"' \
  "$work/gpu.json" || fail "--device gpu: $(cat "$work/gpu.json")"
# Each stage's device as it ran (issue 23's (c)): PML's default optimiser, EMLO, has no GPU
# stage, so only the face measures run on the GPU; --json and the summary line say so.
"$mlclust" mesh "$data/fandisk.off" --algo pml -k 100 -q --device gpu --json > "$work/pml.json" \
  || fail "pml --device gpu"
/usr/bin/python3 -c '
import json, sys
devices = json.load(open(sys.argv[1]))["devices"]
assert devices["cluster"] == "cpu" and devices["measures"] != "cpu", devices' \
  "$work/pml.json" || fail "pml --device gpu: $(cat "$work/pml.json")"
"$mlclust" mesh "$data/fandisk.off" --algo pml -k 100 -q --device gpu > "$work/pml.txt" \
  || fail "pml --device gpu"
grep -q " s with cluster on cpu, measures on " "$work/pml.txt" || fail "pml --device gpu: $(cat "$work/pml.txt")"
# A flag given twice: the last one counts (-k 5 then --clusters 30).
"$mlclust" mesh "$data/fandisk.off" --algo hc -k 5 --clusters 30 -o "$work/twice.labels" -q \
  > /dev/null || fail "a flag given twice"
[ "$(sort -un "$work/twice.labels" | wc -l)" -eq 30 ] || fail "-k 5 --clusters 30: not 30 clusters"
# --help of every command; what a command's help lists is what it parses, and every option
# of the registry (`info --json`) is listed and parsed by mesh or points, so the three
# cannot drift.
"$mlclust" info --json > "$work/registry.json"
for command in serve mesh points energy stats info watch cancel jobs; do
  "$mlclust" "$command" --help > "$work/$command.help" || fail "$command --help failed"
  "$mlclust" "$command" -h | cmp -s - "$work/$command.help" || fail "$command -h differs from --help"
  "$mlclust" help "$command" | cmp -s - "$work/$command.help" || fail "help $command differs"
  sed -n 's/^ *\(-[a-z], \)\{0,1\}--\([a-z0-9-]*\).*/\2/p' "$work/$command.help" | sort -u \
    > "$work/$command.flags"
  [ "$(wc -l < "$work/$command.flags")" -ge 2 ] || fail "$command --help: no flags listed"
  while read -r flag; do
    [ "$flag" = help ] && continue
    # A flag no command has follows, so nothing runs: the parser names the first it does not
    # know, which must be that one.
    expect_bad_flag "unknown option --zz-none" "$command" "--$flag" x --zz-none
  done < "$work/$command.flags"
done
/usr/bin/python3 -c '
import json, sys
info = json.load(open(sys.argv[1]))
for kind, command in (("INPUT_KIND_DRACO_MESH", "mesh"), ("INPUT_KIND_POINTS_F32", "points")):
    listed = set(open(sys.argv[2] + "/" + command + ".flags").read().split())
    for algorithm in info["algorithms"]:
        if algorithm["input_kind"] != kind: continue
        for option in algorithm["options"]:
            assert option["name"] in listed, (command, algorithm["name"], option["name"])
' "$work/registry.json" "$work" || fail "a registry option is missing from mesh or points --help"

# A CLI that behaves: help per command, --version, short flags, JSON, plain connection errors.
"$mlclust" mesh --help > "$work/help.txt" || fail "mesh --help failed"
grep -q -- "--algo ALGO" "$work/help.txt" || fail "mesh --help: no --algo"
grep -q "vsa: variational shape approximation" "$work/help.txt" || fail "mesh --help: no vsa"
# (to a file: grep -q leaving a pipe early would kill a longer help text with SIGPIPE)
"$mlclust" help points > "$work/help_points.txt" || fail "help points failed"
grep -q "kmeans" "$work/help_points.txt" || fail "help points"
version=$(sed -n 's/^project(mlclust VERSION \([0-9.]*\).*/\1/p' "$data/../CMakeLists.txt")
[ "$("$mlclust" --version)" = "mlclust $version" ] || fail "--version is not $version"
"$mlclust" mesh "$data/fandisk.off" --algo hc -k 30 -o "$work/short.labels" -q --json \
  > "$work/summary.json" || fail "short flags"
[ "$(sort -un "$work/short.labels" | wc -l)" -eq 30 ] || fail "-k 30 -o: not 30 clusters"
/usr/bin/python3 -c '
import json, sys
s = json.load(open(sys.argv[1]))
assert s["faces"] == 12946 and s["algorithm"] == "hc" and s["level"]["clusters"] == 30, s
assert s["outputs"]["labels"].endswith("short.labels"), s' "$work/summary.json" \
  || fail "--json summary: $(cat "$work/summary.json")"
"$mlclust" stats --server "127.0.0.1:$port" --json > "$work/stats.json"
/usr/bin/python3 -c 'import json, sys; assert "queue_capacity" in json.load(open(sys.argv[1]))' \
  "$work/stats.json" || fail "stats --json: $(cat "$work/stats.json")"
"$mlclust" info --json > "$work/info.json" || fail "info failed"
/usr/bin/python3 -c '
import json, sys
info = json.load(open(sys.argv[1]))
names = {(a["input_kind"], a["name"]) for a in info["algorithms"]}
assert ("INPUT_KIND_DRACO_MESH", "vsa") in names and ("INPUT_KIND_POINTS_F32", "kmeans") in names
assert info["version"] and info["max_clusters"] == 4294967295' "$work/info.json" \
  || fail "info --json: $(head -c 300 "$work/info.json")"
"$mlclust" info --server "127.0.0.1:$port" --json > "$work/info_remote.json" \
  || fail "info --server failed"
/usr/bin/python3 -c '
import json, sys
local, remote = (json.load(open(p)) for p in sys.argv[1:3])
assert remote["algorithms"] == local["algorithms"], "the server lists other algorithms"
assert remote["version"] == local["version"]' "$work/info.json" "$work/info_remote.json" \
  || fail "info --server: $(head -c 300 "$work/info_remote.json")"
if "$mlclust" stats --server 127.0.0.1:1 2> "$work/conn.err"; then fail "stats on port 1"; fi
grep -q "no server is listening at 127.0.0.1:1" "$work/conn.err" || fail "$(cat "$work/conn.err")"
if "$mlclust" stats --server 127.0.0.1:99999 2> "$work/conn.err"; then fail "port 99999"; fi
grep -q "HOST:PORT" "$work/conn.err" || fail "bad address: $(cat "$work/conn.err")"

# Points: 6 Gaussian blobs (sigma 1, 300 points each, centres 20 apart) as CSV with a
# header; BIC finds 6, through the separate server too.
awk 'BEGIN { srand(7); print "x,y,z";
  for (b = 0; b < 6; ++b) for (i = 0; i < 300; ++i) {
    line = "";
    for (j = 0; j < 3; ++j) {
      u = rand(); if (u < 1e-12) u = 1e-12; v = rand();
      c = (j == b % 3 ? 20 * (1 + int(b / 3)) : 0);
      line = line (j ? "," : "") (c + sqrt(-2 * log(u)) * cos(6.283185307 * v));
    }
    print line } }' > "$work/blobs.csv"
"$mlclust" points "$work/blobs.csv" --algo ml --auto-k bic --labels "$work/blobs.labels" \
  --levels-csv "$work/blobs_levels.csv" --server "127.0.0.1:$port" --quiet > "$work/points.out"
grep -q "BIC highest at 6 clusters" "$work/points.out" || fail "BIC did not find 6: $(cat "$work/points.out")"
[ "$(sort -un "$work/blobs.labels" | wc -l)" -eq 6 ] || fail "points labels: not 6 clusters"
[ "$(wc -l < "$work/blobs.labels")" -eq 1800 ] || fail "points labels: not one line per point"
# LN k-means from the voxel grid: one cluster per occupied voxel, no K; K with it is refused.
"$mlclust" points "$work/blobs.csv" --algo lnkmeans --init grid --grid 4 --labels "$work/grid.labels" \
  --server "127.0.0.1:$port" --quiet > "$work/grid.out" || fail "lnkmeans --init grid failed"
[ "$(sort -un "$work/grid.labels" | wc -l)" -gt 6 ] || fail "lnkmeans --init grid: too few clusters"
if "$mlclust" points "$work/blobs.csv" --algo lnkmeans --init grid --clusters 5 --quiet 2> "$work/grid.err"; then
  fail "--init grid with --clusters accepted"
fi
grep -q "voxel" "$work/grid.err" || fail "no reason given: $(cat "$work/grid.err")"
# k-means: K clusters, the summary names them (level 1 is the result, level 0 the seeding).
"$mlclust" points "$work/blobs.csv" --algo kmeans --clusters 6 --labels "$work/kmeans.labels" \
  --levels-csv "$work/kmeans.csv" --server "127.0.0.1:$port" --quiet > "$work/kmeans.out" \
  || fail "kmeans failed"
[ "$(sort -un "$work/kmeans.labels" | wc -l)" -eq 6 ] || fail "kmeans: not 6 clusters"
[ "$(wc -l < "$work/kmeans.csv")" -eq 3 ] || fail "kmeans: not two levels"
grep -q "level 1: 6 clusters" "$work/kmeans.out" || fail "kmeans summary: $(cat "$work/kmeans.out")"
# A ragged CSV is refused naming the row.
printf '1,2,3\n4,5\n' > "$work/ragged.csv"
if "$mlclust" points "$work/ragged.csv" --quiet 2> "$work/ragged.err"; then fail "ragged CSV accepted"; fi
grep -q "2" "$work/ragged.err" || fail "no row named for the ragged CSV: $(cat "$work/ragged.err")"

# --auto-k elbow for meshes (section 4.4): a cube cut into 8 x 8 squares per side, with the
# planar energy, has its elbow at its 6 sides; fandisk's planar curve rises steadily and has
# none, which is an error that says so.
awk 'BEGIN {
  n = 8; nv = 0; nf = 0
  for (axis = 0; axis < 3; axis++) for (side = 0; side <= n; side += n)
    for (i = 0; i < n; i++) for (j = 0; j < n; j++) {
      for (c = 0; c < 4; c++) {
        a = i + (c == 1 || c == 2); b = j + (c >= 2)
        p[axis] = side; p[(axis + 1) % 3] = a; p[(axis + 2) % 3] = b
        key = p[0] " " p[1] " " p[2]
        if (!(key in id)) { id[key] = nv; vert[nv++] = key }
        q[c] = id[key]
      }
      if (side == 0) { face[nf++] = q[0] " " q[2] " " q[1]; face[nf++] = q[0] " " q[3] " " q[2] }
      else { face[nf++] = q[0] " " q[1] " " q[2]; face[nf++] = q[0] " " q[2] " " q[3] }
    }
  print "OFF"; print nv, nf, 0
  for (v = 0; v < nv; v++) print vert[v]
  for (f = 0; f < nf; f++) print 3, face[f]
}' > "$work/cube.off"
"$mlclust" mesh "$work/cube.off" --energy planar --auto-k elbow --labels "$work/cube.labels" \
  --server "127.0.0.1:$port" > "$work/cube.out" || fail "cube --auto-k elbow failed"
[ "$(sort -un "$work/cube.labels" | wc -l)" -eq 6 ] || fail "cube elbow: $(cat "$work/cube.out")"
grep -q "the first elbow, 6 clusters" "$work/cube.out" || fail "cube summary: $(cat "$work/cube.out")"
if "$mlclust" mesh "$data/fandisk.off" --energy planar --auto-k elbow --labels "$work/f.labels" \
  --server "127.0.0.1:$port" --quiet 2> "$work/fandisk_elbow.err"; then
  fail "fandisk planar: an elbow where the text's definition has none"
fi
grep -q "no elbow by section 4.4" "$work/fandisk_elbow.err" || fail "$(cat "$work/fandisk_elbow.err")"

kill -TERM "$server_pid"
wait "$server_pid" || fail "server exited with an error on SIGTERM"
server_pid=""
echo "cli_test: all checks passed"
