#!/usr/bin/env bash
# Puts the benchmark meshes in data/bench/ (ignored by git): five OFF meshes from CGAL's
# data set, which Debian ships in libcgal-demo, and armadillo_1m.off, the armadillo
# subdivided twice (832,000 faces) for runs at a million-face scale.
#
# Idempotent: installs libcgal-demo only if it is missing, rewrites a file only if its
# content would change, and subdivides only when armadillo_1m.off is missing or older
# than armadillo.off. Needs root (or sudo) only for the install.
#
#   scripts/fetch-bench-meshes.sh            # everything
#   scripts/fetch-bench-meshes.sh --no-1m    # skip the subdivided armadillo
set -euo pipefail

readonly PACKAGE=libcgal-demo
readonly ARCHIVE=/usr/share/doc/libcgal-dev/data.tar.gz
readonly MESHES=(fandisk.off bunny00.off armadillo.off elephant.off fandisk_large.off)

repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bench_dir="$repo_root/data/bench"
make_1m=1
for argument in "$@"; do
  case "$argument" in
    --no-1m) make_1m=0 ;;
    -h | --help) sed -n '2,12p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "fetch-bench-meshes: unknown argument '$argument'" >&2; exit 2 ;;
  esac
done

# --- 1. The package -------------------------------------------------------------------
bash "$repo_root/scripts/apt-ensure.sh" fetch-bench-meshes "$PACKAGE"
[ -f "$ARCHIVE" ] || { echo "fetch-bench-meshes: $ARCHIVE is missing although $PACKAGE is installed" >&2; exit 1; }

# --- 2. The five meshes ----------------------------------------------------------------
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
members=()
for mesh in "${MESHES[@]}"; do members+=("data/meshes/$mesh"); done
tar -xzf "$ARCHIVE" -C "$work" "${members[@]}"

mkdir -p "$bench_dir"
# Prints "name  faces  vertices  bytes  note" for a file written or kept.
report() {
  local file="$1" note="$2" counts
  # The first non-comment line after the OFF keyword holds "vertices faces edges".
  counts="$(awk '!/^[ \t]*(#|$)/ { n++; if (n == 1 && $1 ~ /OFF$/ && NF > 1) { print $2, $3; exit }
                                     if (n == 2) { print $1, $2; exit } }' "$file")"
  printf '  %-22s %8s faces %8s vertices %10s bytes  %s\n' "$(basename "$file")" \
    "${counts#* }" "${counts%% *}" "$(stat -c %s "$file")" "$note"
}

echo "fetch-bench-meshes: $bench_dir"
for mesh in "${MESHES[@]}"; do
  source_file="$work/data/meshes/$mesh"
  target="$bench_dir/$mesh"
  if [ -f "$target" ] && cmp -s "$source_file" "$target"; then
    report "$target" "(unchanged)"
  else
    cp "$source_file" "$target.tmp" && mv "$target.tmp" "$target"
    report "$target" "(written)"
  fi
done

# --- 3. A million-face armadillo -------------------------------------------------------
if [ "$make_1m" -eq 1 ]; then
  source_file="$bench_dir/armadillo.off"
  target="$bench_dir/armadillo_1m.off"
  if [ -f "$target" ] && [ "$target" -nt "$source_file" ]; then
    report "$target" "(unchanged)"
  else
    python="/usr/bin/python3"
    [ -x "$python" ] || python="$(command -v python3)"
    # Midpoint (1-to-4) subdivision, twice: 52,000 faces become 832,000. Face i becomes
    # faces 4i .. 4i+3 (corner triangles, then the middle one), all counter-clockwise
    # like the input; edge midpoints are shared, so the result stays a closed manifold.
    "$python" - "$source_file" "$target.tmp" <<'PYTHON'
import sys

def read_off(path):
    tokens = []
    with open(path) as f:
        for line in f:
            tokens.extend(line.split("#", 1)[0].split())
    if tokens[0].endswith("OFF"):
        tokens = tokens[1:]
    num_vertices, num_faces = int(tokens[0]), int(tokens[1])
    at = 3
    vertices = [tuple(float(x) for x in tokens[at + 3 * i: at + 3 * i + 3])
                for i in range(num_vertices)]
    at += 3 * num_vertices
    faces = []
    for _ in range(num_faces):
        n = int(tokens[at])
        if n != 3:
            sys.exit("fetch-bench-meshes: %s has a face of %d corners" % (path, n))
        faces.append((int(tokens[at + 1]), int(tokens[at + 2]), int(tokens[at + 3])))
        at += 4
    return vertices, faces

def subdivide(vertices, faces):
    vertices = list(vertices)
    midpoint_of = {}
    def midpoint(a, b):
        key = (a, b) if a < b else (b, a)
        index = midpoint_of.get(key)
        if index is None:
            pa, pb = vertices[a], vertices[b]
            index = len(vertices)
            vertices.append(tuple((x + y) * 0.5 for x, y in zip(pa, pb)))
            midpoint_of[key] = index
        return index
    result = []
    for a, b, c in faces:
        ab, bc, ca = midpoint(a, b), midpoint(b, c), midpoint(c, a)
        result += [(a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca)]
    return vertices, result

vertices, faces = read_off(sys.argv[1])
for _ in range(2):
    vertices, faces = subdivide(vertices, faces)
with open(sys.argv[2], "w") as out:
    out.write("OFF\n%d %d 0\n" % (len(vertices), len(faces)))
    out.writelines("%.9g %.9g %.9g\n" % v for v in vertices)
    out.writelines("3 %d %d %d\n" % f for f in faces)
PYTHON
    mv "$target.tmp" "$target"
    report "$target" "(written: armadillo.off subdivided twice)"
  fi
fi
