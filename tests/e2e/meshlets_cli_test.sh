#!/usr/bin/env bash
# `mlclust mesh INPUT --meshlets FILE --labels FILE`: the file's header and sizes, the caps of
# every meshlet (read back with Python's struct), one label per face, and the refusals.
#   meshlets_cli_test.sh MLCLUST DATA_DIR
set -euo pipefail
mlclust="$1"
data="$2"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

"$mlclust" mesh "$data/elephant-with-holes.off" --meshlets "$work/m.bin" --labels "$work/l.txt" \
  --max-vertices 32 --max-triangles 40 > "$work/out.txt"
grep -q "meshlets (at most 32 vertices, 40 triangles" "$work/out.txt"
faces="$(awk '!/^[ \t]*(#|$)/ { n++; if (n == 2) { print $2; exit } }' "$data/elephant-with-holes.off")"
[ "$(wc -l < "$work/l.txt")" -eq "$faces" ] || { echo "labels: not one per face" >&2; exit 1; }
python3 - "$work/m.bin" "$work/l.txt" "$faces" <<'PY'
import struct, sys
data = open(sys.argv[1], "rb").read()
labels = [int(x) for x in open(sys.argv[2])]
faces = int(sys.argv[3])
assert data[:8] == b"MLCMSHLT", data[:8]
(version, header, max_v, max_t, m, n, b, f, v, flags) = struct.unpack_from("<10I", data, 8)
assert (version, header, max_v, max_t, f, flags) == (1, 64, 32, 40, faces, 1)
assert len(data) == 64 + 16 * m + 4 * n + b + 4 * f + 48 * m, "sizes"
meshlets = [struct.unpack_from("<4I", data, 64 + 16 * i) for i in range(m)]
faces_at = 64 + 16 * m + 4 * n + b
tri_faces = struct.unpack_from("<%dI" % f, data, faces_at)
seen, t = set(), 0
for i, (vo, to, vc, tc) in enumerate(meshlets):
    assert 1 <= tc <= 40 and vc <= 32 and to % 4 == 0, (i, vc, tc, to)
    for k in range(tc):
        assert labels[tri_faces[t]] == i
        seen.add(tri_faces[t]); t += 1
    local = data[64 + 16 * m + 4 * n + to: 64 + 16 * m + 4 * n + to + 3 * tc]
    assert max(local) < vc
assert len(seen) == faces == t
PY
# FILE.glb: a glTF 2.0 binary whose mesh extras name the meshlet views.
"$mlclust" mesh "$data/elephant.off" --meshlets "$work/m.glb" > /dev/null
python3 - "$work/m.glb" <<'PY'
import json, struct, sys
data = open(sys.argv[1], "rb").read()
magic, version, length, json_length, kind = struct.unpack_from("<4sIII4s", data, 0)
assert (magic, version, length, kind) == (b"glTF", 2, len(data), b"JSON")
gltf = json.loads(data[20:20 + json_length])
extras = gltf["meshes"][0]["extras"]["mlclust_meshlets"]
assert extras["version"] == 1 and extras["max_vertices"] == 64 and extras["meshlet_count"] > 0
assert gltf["accessors"][1]["count"] == 3 * 5558
PY
# Refusals: caps out of range, a flag of the clustering job.
if "$mlclust" mesh "$data/elephant.off" --meshlets "$work/x.bin" --max-vertices 256 2> "$work/err.txt"; then
  echo "--max-vertices 256 accepted" >&2; exit 1
fi
grep -q "max-vertices" "$work/err.txt"
if "$mlclust" mesh "$data/elephant.off" --meshlets "$work/x.bin" --clusters 4 2> "$work/err.txt"; then
  echo "--clusters beside --meshlets accepted" >&2; exit 1
fi
grep -q "drop --clusters" "$work/err.txt"
echo "meshlets CLI: ok"
