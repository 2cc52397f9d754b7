#!/usr/bin/python3
"""Renders a clustered PLY written by mlclust (--ply) to a PNG with matplotlib.

    /usr/bin/python3 bench/render_ply.py IN.ply OUT.png [--elev 20 --azim 30] [--title T]

Needs Debian's python3-numpy and python3-matplotlib (scripts/install-deps.sh --bench).
Reads the binary little-endian layout mlclust writes: float x y z, uchar r g b per vertex;
uchar-counted int vertex_indices and uchar r g b per face.
"""
import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402


def read_ply(path):
    with open(path, "rb") as f:
        header = []
        while True:
            line = f.readline().decode("ascii").strip()
            header.append(line)
            if line == "end_header":
                break
        counts = {}
        for line in header:
            if line.startswith("element"):
                _, name, n = line.split()
                counts[name] = int(n)
        vertex = np.dtype([("p", "<f4", 3), ("c", "u1", 3)])
        vertices = np.frombuffer(f.read(vertex.itemsize * counts["vertex"]), dtype=vertex)
        face = np.dtype([("n", "u1"), ("i", "<i4", 3), ("c", "u1", 3)])
        faces = np.frombuffer(f.read(face.itemsize * counts["face"]), dtype=face)
    return vertices["p"], faces["i"], faces["c"] / 255.0


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("ply")
    parser.add_argument("png")
    parser.add_argument("--elev", type=float, default=20)
    parser.add_argument("--azim", type=float, default=35)
    parser.add_argument("--title", default="")
    args = parser.parse_args()
    positions, triangles, colours = read_ply(args.ply)
    corners = positions[triangles]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-30)
    light = np.array([0.3, 0.4, 0.85])
    shade = 0.45 + 0.55 * np.abs(normals @ (light / np.linalg.norm(light)))
    fig = plt.figure(figsize=(8, 8), dpi=110)
    ax = fig.add_subplot(projection="3d")
    ax.add_collection3d(Poly3DCollection(corners, facecolors=colours * shade[:, None],
                                         edgecolors="none"))
    lo, hi = positions.min(axis=0), positions.max(axis=0)
    centre, radius = (lo + hi) / 2, (hi - lo).max() / 2
    for set_lim, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre):
        set_lim(c - radius, c + radius)
    ax.view_init(elev=args.elev, azim=args.azim)
    ax.set_axis_off()
    if args.title:
        ax.set_title(args.title)
    fig.savefig(args.png, bbox_inches="tight")


if __name__ == "__main__":
    main()
