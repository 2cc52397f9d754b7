#!/usr/bin/python3
"""Writes the faces of an OFF mesh within a few vertex rings of given vertices as a small OFF
file (for test fixtures: tests/fixtures/cgal_polygon_mesh_crop.off).

Faces keep their relative order; vertices are renumbered in order of first use by the kept
faces. Polygons are kept as written (triangles in the CGAL demo mesh).

  crop_nonmanifold.py IN.off OUT.off --vertices 4113,4349 --rings 2

The non-manifold vertices of a mesh are what `repair_report IN.off` (bench/experiments)
lists.
"""
import argparse


def read_off(path):
    with open(path) as f:
        words = [line.split("#")[0].split() for line in f]
    words = [w for w in words if w]
    if words[0][0] != "OFF":
        raise SystemExit(f"{path}: not an OFF file")
    counts = words[0][1:] if len(words[0]) > 1 else words[1]
    start = 1 if len(words[0]) > 1 else 2
    nv, nf = int(counts[0]), int(counts[1])
    vertices = [w[:3] for w in words[start:start + nv]]
    faces = [[int(x) for x in w[1:1 + int(w[0])]] for w in words[start + nv:start + nv + nf]]
    return vertices, faces


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("input")
    parser.add_argument("output")
    parser.add_argument("--vertices", required=True)
    parser.add_argument("--rings", type=int, default=2)
    args = parser.parse_args()
    vertices, faces = read_off(args.input)
    region = {int(v) for v in args.vertices.split(",")}
    kept = set()
    for _ in range(args.rings):
        kept = {i for i, f in enumerate(faces) if region.intersection(f)}
        region = {v for i in kept for v in faces[i]}
    order = sorted(kept)
    number = {}
    for i in order:
        for v in faces[i]:
            number.setdefault(v, len(number))
    with open(args.output, "w") as out:
        out.write(f"OFF\n# {len(order)} faces of {args.input.split('/')[-1]} within "
                  f"{args.rings} rings of vertices {args.vertices} (crop_nonmanifold.py)\n")
        out.write(f"{len(number)} {len(order)} 0\n")
        for v, _ in sorted(number.items(), key=lambda item: item[1]):
            out.write(" ".join(vertices[v]) + "\n")
        for i in order:
            out.write(f"{len(faces[i])} " + " ".join(str(number[v]) for v in faces[i]) + "\n")


if __name__ == "__main__":
    main()
