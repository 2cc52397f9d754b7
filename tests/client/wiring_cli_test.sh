#!/usr/bin/env bash
# The library pieces wired into the CLI (issues 11 and 13), end to end through the embedded
# server: X-means and bisecting k-means on points; on meshes --planar-merge, --repair,
# --plot, --coarse's exit code 3 and vertex placement, and the edgebreaker upload with
# per-face ids.
#   wiring_cli_test.sh MLCLUST_BINARY DATA_DIR
set -euo pipefail
mlclust=$1
data=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

# Five well-separated Gaussian blobs of 100 points in 2-D (sigma 1, centres 20 apart), and
# the blob of each point.
/usr/bin/python3 -c '
import numpy as np, sys
r = np.random.default_rng(1)
c = np.array([[0, 0], [20, 0], [0, 20], [20, 20], [40, 40]], float)
np.save(sys.argv[1], np.concatenate([ci + r.normal(size=(100, 2)) for ci in c]).astype(np.float32))
np.savetxt(sys.argv[2], np.repeat(np.arange(5), 100), fmt="%d")
' "$work/blobs.npy" "$work/truth.txt"

# The same partition as the blobs (labels equal up to renaming).
same_partition() {
  /usr/bin/python3 -c '
import sys
a = [l.strip() for l in open(sys.argv[1])]
b = [l.strip() for l in open(sys.argv[2])]
assert len(a) == len(b), (len(a), len(b))
assert len(set(zip(a, b))) == len(set(a)) == len(set(b)), "partitions differ"
' "$1" "$2"
}

# X-means (Alg. 2.5) from k_min = 1 finds the five blobs; --labels writes the K it found.
"$mlclust" points "$work/blobs.npy" --algo xmeans --clusters 1 --kmax 20 \
  --labels "$work/xmeans.txt" --levels-csv "$work/xmeans.csv" --json --quiet > "$work/xmeans.json"
[ "$(wc -l < "$work/xmeans.txt")" -eq 500 ] || fail "xmeans: not one label per point"
same_partition "$work/xmeans.txt" "$work/truth.txt" || fail "xmeans: not the five blobs"
/usr/bin/python3 -c '
import json, sys
j = json.load(open(sys.argv[1]))
assert j["algorithm"] == "xmeans" and j["final_clusters"] == 5 and j["levels"] == 2, j
assert j["level"]["clusters"] == 5, j
' "$work/xmeans.json" || fail "xmeans: summary $(cat "$work/xmeans.json")"
# Level 0 is the k-means at k_min = 1 (one cluster), level 1 the result.
[ "$(sed -n 2p "$work/xmeans.csv" | cut -d, -f1)" = 1 ] || fail "xmeans: level 0 not at k_min"
[ "$(sed -n 3p "$work/xmeans.csv" | cut -d, -f1)" = 5 ] || fail "xmeans: level 1 not at 5"
# k_max below k_min is a bad argument (exit 2), named.
if "$mlclust" points "$work/blobs.npy" --algo xmeans --clusters 5 --kmax 3 --quiet \
  2> "$work/kmax.err"; then
  fail "xmeans: kmax < k_min accepted"
else
  [ $? -eq 2 ] || fail "xmeans: kmax < k_min: exit not 2"
fi
grep -q "kmax" "$work/kmax.err" || fail "xmeans: no message naming kmax: $(cat "$work/kmax.err")"

# Bisecting k-means (Alg. 2.7): levels from K = 8 down to 1; the level with 5 clusters,
# splitting the cluster of largest energy with the best of 5 k-means++ 2-means (a cut made
# early is never undone: with one random 2-means a blob is cut),
# is the five blobs.
bisect="--split energy --trials 5 --init kmeans++"
"$mlclust" points "$work/blobs.npy" --algo bisecting --clusters 8 $bisect \
  --levels-csv "$work/bisecting.csv" --quiet > /dev/null
[ "$(cut -d, -f1 "$work/bisecting.csv" | tr '\n' ' ')" = "clusters 8 7 6 5 4 3 2 1 " ] \
  || fail "bisecting: levels $(cut -d, -f1 "$work/bisecting.csv" | tr '\n' ' ')"
"$mlclust" points "$work/blobs.npy" --algo bisecting --clusters 5 $bisect \
  --labels "$work/bisecting.txt" --quiet > /dev/null
same_partition "$work/bisecting.txt" "$work/truth.txt" || fail "bisecting: not the five blobs"
# A hierarchy: --auto-k bic picks a level (the five blobs score highest among 8..1).
"$mlclust" points "$work/blobs.npy" --algo bisecting --clusters 8 $bisect --auto-k bic \
  --labels "$work/bic.txt" --quiet > "$work/bic.out"
same_partition "$work/bic.txt" "$work/truth.txt" || fail "bisecting --auto-k bic: $(cat "$work/bic.out")"
# Without K: a bad argument.
if "$mlclust" points "$work/blobs.npy" --algo bisecting --quiet 2> "$work/nok.err"; then
  fail "bisecting without --clusters accepted"
fi
grep -q "clusters" "$work/nok.err" || fail "bisecting: no message naming --clusters"

# --planar-merge (Delta_merging, l. 1285) after planar EMLO: fewer clusters, and the labels
# written are the merged ones; refused after a non-planar clustering.
"$mlclust" mesh "$data/fandisk.off" --algo emlo --energy planar --clusters 70 --init random \
  --seed 1 --planar-merge 1 --labels "$work/merged.txt" --quiet > "$work/merged.out"
merged=$(sort -un "$work/merged.txt" | wc -l)
[ "$merged" -lt 70 ] || fail "planar merge: still $merged clusters"
grep -q -- "70 -> $merged clusters" "$work/merged.out" || fail "planar merge: $(cat "$work/merged.out")"
if "$mlclust" mesh "$data/fandisk.off" --algo emlo --clusters 70 --planar-merge 1 --quiet \
  2> "$work/merge_cvd.err"; then
  fail "planar merge after a CVD clustering accepted"
fi
grep -q "planar clustering" "$work/merge_cvd.err" || fail "planar merge: no message for cvd"

# --plot: a PNG of the levels' energies.
"$mlclust" mesh "$data/fandisk.off" --algo hc --clusters 10 --plot "$work/curve.png" --quiet \
  > /dev/null
[ "$(head -c 4 "$work/curve.png" | od -An -tx1 | tr -d ' ')" = 89504e47 ] || fail "plot: not a PNG"
/usr/bin/python3 -c '
import struct, sys
b = open(sys.argv[1], "rb").read(24)
assert struct.unpack(">II", b[16:24]) == (900, 560), b[16:24]
' "$work/curve.png" || fail "plot: not 900 x 560"

# --coarse at a K with no coarse mesh (fandisk at 2 clusters: no corner of three): exit 3,
# the labels written, the message names them and the nearest K that coarsens, which does.
set +e
"$mlclust" mesh "$data/fandisk.off" --clusters 2 --labels "$work/k2.txt" \
  --coarse "$work/k2.obj" --quiet > /dev/null 2> "$work/k2.err"
code=$?
set -e
[ "$code" -eq 3 ] || fail "coarse at K=2: exit $code, not 3: $(cat "$work/k2.err")"
[ "$(wc -l < "$work/k2.txt")" -eq 12946 ] || fail "coarse at K=2: labels not written"
[ ! -e "$work/k2.obj" ] || fail "coarse at K=2: a coarse file was written"
grep -q -- "written: --labels $work/k2.txt" "$work/k2.err" || fail "coarse: $(cat "$work/k2.err")"
nearest=$(sed -n 's/.*coarsens has \([0-9]*\) clusters.*/\1/p' "$work/k2.err")
[ -n "$nearest" ] || fail "coarse: no nearest K: $(cat "$work/k2.err")"
"$mlclust" mesh "$data/fandisk.off" --clusters "$nearest" --coarse "$work/near.obj" --quiet \
  > /dev/null || fail "coarse: the nearest K $nearest does not coarsen"
[ -s "$work/near.obj" ] || fail "coarse: no file at the nearest K"

# --repair on CGAL's non-manifold polygon_mesh.off (libcgal-demo's data), else on the crop of
# it in tests/fixtures: refused as it is; with --repair it runs, says what it split, and
# the labels are one per input face.
nonmanifold="$data/../tests/fixtures/cgal_polygon_mesh_crop.off"
if [ -r /usr/share/doc/libcgal-dev/data.tar.gz ] && tar xzf /usr/share/doc/libcgal-dev/data.tar.gz \
  -O data/meshes/polygon_mesh.off > "$work/polygon_mesh.off" 2> /dev/null; then
  nonmanifold="$work/polygon_mesh.off"
fi
faces=$(awk 'NR > 1 && !/^#/ && NF == 3 { print $2; exit }' "$nonmanifold")
if "$mlclust" mesh "$nonmanifold" --quiet 2> "$work/nm.err" > /dev/null; then
  fail "repair: the non-manifold mesh was accepted without --repair"
fi
grep -q "non-manifold" "$work/nm.err" || fail "repair: no message: $(cat "$work/nm.err")"
"$mlclust" mesh "$nonmanifold" --repair --clusters 20 --labels "$work/repaired.txt" --quiet \
  > /dev/null 2> "$work/repair.err" || fail "repair: $(cat "$work/repair.err")"
grep -q "split .* vertices.*face ids unchanged" "$work/repair.err" \
  || fail "repair: did not say what it changed: $(cat "$work/repair.err")"
[ "$(wc -l < "$work/repaired.txt")" -eq "$faces" ] || fail "repair: not one label per input face"
[ "$(sort -un "$work/repaired.txt" | wc -l)" -eq 20 ] || fail "repair: not 20 clusters"

# The edgebreaker upload with per-face ids: the server puts the faces back in the input's
# order, so HC's labels and every level are those of the sequential upload; it is smaller.
"$mlclust" mesh "$data/fandisk.off" --algo hc --clusters 100 --labels "$work/seq.txt" \
  --levels-csv "$work/seq.csv" --json --quiet > "$work/seq.json"
"$mlclust" mesh "$data/fandisk.off" --algo hc --clusters 100 --labels "$work/eb.txt" \
  --levels-csv "$work/eb.csv" --upload edgebreaker --json --quiet > "$work/eb.json"
cmp -s "$work/seq.txt" "$work/eb.txt" || fail "edgebreaker: labels differ from sequential"
cmp -s "$work/seq.csv" "$work/eb.csv" || fail "edgebreaker: levels differ from sequential"
/usr/bin/python3 -c '
import json, sys
s, e = (json.load(open(f))["upload"] for f in sys.argv[1:3])
assert s["method"] == "sequential" and e["method"] == "edgebreaker+face-ids", (s, e)
assert e["bytes"] < s["bytes"], (s, e)
# Accepted says where the ids came from (the attribute, or the decoded order).
assert e["face_ids"] is True and "mlclust_face_id" in e["face_order"], e
assert s["face_ids"] is False and "decoded face order" in s["face_order"], s
' "$work/seq.json" "$work/eb.json" || fail "edgebreaker: upload $(cat "$work/eb.json")"

# --per-polygon on a quad grid (12 x 12 quads, a wavy height): ML on the triangles splits
# some quads between clusters; with --per-polygon the server clusters whole quads
# (JobSpec.polygon_triangle_counts): --labels has one line per quad and the summary says
# none was split. With --algo vsa (per triangle on the server) the post-pass still runs.
/usr/bin/python3 -c '
import math, sys
n = 12
with open(sys.argv[1], "w") as f:
    f.write("OFF\n%d %d 0\n" % ((n + 1) ** 2, n * n))
    for j in range(n + 1):
        for i in range(n + 1):
            f.write("%g %g %g\n" % (i, j, 0.15 * math.sin(0.7 * i) + 0.1 * math.cos(0.9 * j)))
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i
            f.write("4 %d %d %d %d\n" % (a, a + 1, a + n + 2, a + n + 1))
' "$work/quads.off"
"$mlclust" mesh "$work/quads.off" --clusters 10 --labels "$work/triangles.txt" --quiet > /dev/null
"$mlclust" mesh "$work/quads.off" --clusters 10 --labels "$work/polygons.txt" --per-polygon \
  --quiet > "$work/polygons.out"
[ "$(wc -l < "$work/polygons.txt")" -eq 144 ] || fail "per-polygon: not one line per quad"
/usr/bin/python3 -c '
import sys
t = open(sys.argv[1]).read().split()
p = open(sys.argv[2]).read().split()
split = [q for q in range(144) if t[2 * q] != t[2 * q + 1]]
assert split, "no quad was split on the triangles: the test shows nothing"
assert len(set(p)) == 10, "not 10 clusters"
with open(sys.argv[3], "w") as f:
    f.write("".join(l + "\n" + l + "\n" for l in p))
' "$work/triangles.txt" "$work/polygons.txt" "$work/expanded.txt" \
  || fail "per-polygon: labels"
grep -q "144 polygons, each one element of the clustering (none split)" "$work/polygons.out" \
  || fail "per-polygon: $(cat "$work/polygons.out")"
"$mlclust" mesh "$work/quads.off" --algo vsa --energy planar --clusters 6 --per-polygon \
  --labels "$work/polygons_vsa.txt" --quiet > "$work/polygons_vsa.out"
grep -q "were split and went to the cluster of most of their area" "$work/polygons_vsa.out" \
  || fail "per-polygon post-pass (vsa): $(cat "$work/polygons_vsa.out")"
[ "$(wc -l < "$work/polygons_vsa.txt")" -eq 144 ] || fail "per-polygon vsa: not one line per quad"
# The same grid as OBJ: the same polygon labels.
/usr/bin/python3 -c '
import sys
lines = open(sys.argv[1]).read().split("\n")
nv, nf = map(int, lines[1].split()[:2])
with open(sys.argv[2], "w") as f:
    for l in lines[2:2 + nv]:
        f.write("v " + l + "\n")
    for l in lines[2 + nv:2 + nv + nf]:
        f.write("f " + " ".join(str(int(w) + 1) for w in l.split()[1:]) + "\n")
' "$work/quads.off" "$work/quads.obj"
"$mlclust" mesh "$work/quads.obj" --clusters 10 --labels "$work/polygons_obj.txt" --per-polygon \
  --quiet > /dev/null
cmp -s "$work/polygons.txt" "$work/polygons_obj.txt" || fail "per-polygon: OBJ differs from OFF"
reported=$(sed -n 's/.*per polygon:.*energy \([0-9.e+-]*\)$/\1/p' "$work/polygons.out")
recomputed=$("$mlclust" energy "$work/quads.off" --labels "$work/expanded.txt")
/usr/bin/env awk -v a="$reported" -v b="$recomputed" 'BEGIN {
  d = a - b; if (d < 0) d = -d; exit !(d <= 1e-9 * b) }' \
  || fail "per-polygon: reported energy $reported != recomputed $recomputed"

# The proto lists every option key of the registry with type, range and default
# (JobSpec.options): the block is the registry's, regenerated by scripts/proto_options_doc.py.
root="$data/.."
/usr/bin/python3 "$root/scripts/proto_options_doc.py" "$mlclust" > "$work/options_doc.txt"
sed -n '/  \/\/ BEGIN options/,/  \/\/ END options/p' "$root/proto/mlclust/v1/mlclust.proto" \
  > "$work/options_proto.txt"
diff "$work/options_doc.txt" "$work/options_proto.txt" > "$work/options.diff" || fail \
  "the proto's option list differs from the registry's: run /usr/bin/python3 \
scripts/proto_options_doc.py build/client/mlclust --write proto/mlclust/v1/mlclust.proto
$(cat "$work/options.diff")"

# --coarse places each vertex where the clustering's energy has its cluster centre (issue 26
# item 1): adaptive CVD at the density-weighted centroid sum rho A g / sum rho A (l. 783,
# 937), with rho from eq. 3.17 and the power mapping recomputed here; uniform CVD at
# sum A g / sum A (l. 715). Fandisk, EMLO, 200 clusters.
coarse_check() {  # OFF LABELS OBJ weighted|uniform
  /usr/bin/python3 -c '
import sys
import numpy as np
off, labels_path, obj, mode = sys.argv[1:5]
words = [l.split() for l in open(off) if l.strip() and not l.startswith("#")]
nv, nf = int(words[1][0]), int(words[1][1])
v = np.array([[float(x) for x in w[:3]] for w in words[2:2 + nv]])
f = np.array([[int(x) for x in w[1:4]] for w in words[2 + nv:2 + nv + nf]])
p = v[f]
cross = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
area = 0.5 * np.linalg.norm(cross, axis=1)
normal = cross / np.linalg.norm(cross, axis=1)[:, None]
g = p.mean(axis=1)
incident = [[] for _ in range(nv)]
for face, corners in enumerate(f):
    for c in corners: incident[c].append(face)
rho_prime = np.zeros(nf)
for face, corners in enumerate(f):
    ks = [k for c in corners for k in incident[c]]
    rho_prime[face] = np.linalg.norm(normal[ks] - normal[face], axis=1).sum() / len(ks)
rho = (rho_prime + 0.01) ** 2
labels = np.loadtxt(labels_path, dtype=int)
got = np.array([[float(x) for x in l.split()[1:4]] for l in open(obj) if l.startswith("v ")])
k = labels.max() + 1
assert len(got) == k, (len(got), k)
def centroids(mass):
    m = np.bincount(labels, mass, k)
    return np.stack([np.bincount(labels, mass * g[:, j], k) for j in range(3)], 1) / m[:, None]
def distances(expected):
    return np.linalg.norm(got[:, None] - expected[None], axis=2).min(axis=1)
weighted, uniform = distances(centroids(rho * area)), distances(centroids(area))
if mode == "weighted":
    assert weighted.max() < 1e-5, "not at sum rho A g / sum rho A: %g" % weighted.max()
    assert (uniform > 1e-4).sum() > k // 2, "the density moved few vertices"
else:
    assert uniform.max() < 1e-5, "not at sum A g / sum A: %g" % uniform.max()
' "$@"
}
"$mlclust" mesh "$data/fandisk.off" --algo emlo --energy cvd-adaptive --density power \
  --delta 0.01 --gamma 2 --clusters 200 --labels "$work/adaptive.txt" \
  --coarse "$work/adaptive.obj" --quiet > /dev/null || fail "coarse: cvd-adaptive"
coarse_check "$data/fandisk.off" "$work/adaptive.txt" "$work/adaptive.obj" weighted ||
  fail "coarse: cvd-adaptive vertices"
"$mlclust" mesh "$data/fandisk.off" --algo emlo --energy cvd --clusters 200 \
  --labels "$work/uniform.txt" --coarse "$work/uniform.obj" --quiet > /dev/null ||
  fail "coarse: cvd"
coarse_check "$data/fandisk.off" "$work/uniform.txt" "$work/uniform.obj" uniform ||
  fail "coarse: cvd vertices"

echo "PASS"
