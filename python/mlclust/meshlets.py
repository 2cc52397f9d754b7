"""The meshlet file of `mlclust mesh INPUT --meshlets FILE`, read into numpy arrays.

    m = mlclust.read_meshlets("armadillo.meshlets")
    m.meshlets            # (M, 4) uint32: vertex_offset, triangle_offset (bytes), vertex_count,
                          # triangle_count (meshoptimizer's meshopt_Meshlet)
    m.meshlet_vertices    # (N,) uint32 input vertex indices
    m.meshlet_triangles   # (B,) uint8 local indices, 3 per triangle, runs padded to 4 bytes
    m.triangle_faces      # (F,) uint32: the input face of each meshlet triangle, in order
    m.face_meshlet        # (F,) uint32: each input face's meshlet
    m.bounds              # (M,) structured: center, radius, cone_apex, cone_axis, cone_cutoff,
                          # cone_axis_s8, cone_cutoff_s8 (meshopt_Bounds), or None
    m.triangles(k)        # (T, 3) uint32 input vertex indices of meshlet k's triangles

The layout (little-endian) is documented in core/meshlets/meshlet_file.h and in
`mlclust mesh --help`; this reader checks the header and the sizes, and each local index
against its meshlet's vertex count.
"""

from dataclasses import dataclass
from typing import Optional

import numpy as np

MAGIC = b"MLCMSHLT"
VERSION = 1
HEADER_BYTES = 64

BOUNDS_DTYPE = np.dtype([("center", "<f4", 3), ("radius", "<f4"), ("cone_apex", "<f4", 3),
                         ("cone_axis", "<f4", 3), ("cone_cutoff", "<f4"),
                         ("cone_axis_s8", "i1", 3), ("cone_cutoff_s8", "i1")])
assert BOUNDS_DTYPE.itemsize == 48


@dataclass
class Meshlets:
    max_vertices: int
    max_triangles: int
    vertex_count: int
    meshlets: np.ndarray
    meshlet_vertices: np.ndarray
    meshlet_triangles: np.ndarray
    triangle_faces: np.ndarray
    face_meshlet: np.ndarray
    bounds: Optional[np.ndarray]

    def triangles(self, k: int) -> np.ndarray:
        """Meshlet k's triangles as input vertex indices, (triangle_count, 3)."""
        vertex_offset, triangle_offset, _, triangle_count = (int(x) for x in self.meshlets[k])
        local = self.meshlet_triangles[triangle_offset:triangle_offset + 3 * triangle_count]
        return self.meshlet_vertices[vertex_offset + local.astype(np.int64)].reshape(-1, 3)


def read_meshlets(path: str) -> Meshlets:
    """Reads a meshlet file; ValueError naming what is wrong."""
    with open(path, "rb") as f:
        data = f.read()
    if len(data) < HEADER_BYTES:
        raise ValueError(f"{path}: {len(data)} bytes, shorter than the 64-byte header")
    if data[:8] != MAGIC:
        raise ValueError(f"{path}: no MLCMSHLT magic at byte 0")
    fields = np.frombuffer(data, "<u4", 10, 8)
    version, header, max_v, max_t, m, n, b, faces, vertices, flags = (int(x) for x in fields)
    if version != VERSION or header != HEADER_BYTES:
        raise ValueError(f"{path}: version {version}, header {header}; this reader knows 1, 64")
    if flags & ~1:
        raise ValueError(f"{path}: unknown flags {flags}")
    expected = HEADER_BYTES + 16 * m + 4 * n + b + 4 * faces + (48 * m if flags & 1 else 0)
    if expected != len(data):
        raise ValueError(f"{path}: {len(data)} bytes where the header's counts make {expected}")
    at = HEADER_BYTES
    meshlets = np.frombuffer(data, "<u4", 4 * m, at).reshape(m, 4)
    at += 16 * m
    meshlet_vertices = np.frombuffer(data, "<u4", n, at)
    at += 4 * n
    meshlet_triangles = np.frombuffer(data, "u1", b, at)
    at += b
    triangle_faces = np.frombuffer(data, "<u4", faces, at)
    at += 4 * faces
    bounds = np.frombuffer(data, BOUNDS_DTYPE, m, at) if flags & 1 else None
    counts = meshlets[:, 3].astype(np.int64)
    if counts.sum() != faces or (meshlets[:, 1] % 4).any():
        raise ValueError(f"{path}: the meshlets' triangles do not make the {faces} faces")
    if (meshlet_vertices >= vertices).any():
        raise ValueError(f"{path}: a meshlet vertex index is not below {vertices}")
    owner = np.repeat(np.arange(m, dtype=np.int64), 3 * counts)
    starts = np.repeat(meshlets[:, 1].astype(np.int64), 3 * counts)
    within = np.arange(3 * faces, dtype=np.int64) - np.repeat(np.cumsum(3 * counts) - 3 * counts,
                                                              3 * counts)
    local = meshlet_triangles[starts + within]
    if (local >= meshlets[owner, 2]).any():
        raise ValueError(f"{path}: a local index is not below its meshlet's vertex count")
    face_meshlet = np.empty(faces, np.uint32)
    face_meshlet[triangle_faces] = np.repeat(np.arange(m, dtype=np.uint32), counts)
    return Meshlets(max_v, max_t, vertices, meshlets, meshlet_vertices, meshlet_triangles,
                    triangle_faces, face_meshlet, bounds)
