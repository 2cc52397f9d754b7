"""Mesh files with the same readers and writers as the CLI (core/io, through ctypes)."""

import ctypes
import os

import numpy as np

from . import _draco


def _fail(code, error):
    from .client import Error  # Error lives with the client; imported late to avoid a cycle
    raise Error(code, error.value.decode("utf-8", "replace"))


def read_mesh(path):
    """Reads a triangle mesh as the CLI does (OBJ, PLY, OFF, STL, glTF/GLB, Draco-
    compressed glTF, .drc): returns (vertices (V, 3) float32, faces (F, 3) uint32), face
    i being the file's i-th triangle (polygons are split in place), the id every output
    uses. Raises mlclust.Error (NOT_FOUND, INVALID_ARGUMENT naming the file, ...)."""
    lib = _draco._library()
    positions, indices = ctypes.c_void_p(), ctypes.c_void_p()
    nv, nf = ctypes.c_uint64(), ctypes.c_uint64()
    error = ctypes.create_string_buffer(2048)
    code = lib.mlclust_read_mesh(os.fsencode(path), ctypes.byref(positions), ctypes.byref(nv),
                                 ctypes.byref(indices), ctypes.byref(nf), error, len(error))
    if code != 0:
        _fail(code, error)
    try:
        vertices = np.ctypeslib.as_array(
            ctypes.cast(positions, ctypes.POINTER(ctypes.c_float)), (nv.value * 3,)).copy()
        faces = np.ctypeslib.as_array(
            ctypes.cast(indices, ctypes.POINTER(ctypes.c_uint32)), (nf.value * 3,)).copy()
    finally:
        lib.mlclust_draco_free(positions)
        lib.mlclust_draco_free(indices)
    return vertices.reshape(-1, 3), faces.reshape(-1, 3)


def write_clustered(path, vertices, faces, labels):
    """Writes the mesh with one cluster id per face (-1: none), by extension, as the CLI's
    --out: .ply (the input's vertices, an int `cluster` face property and a colour per
    face), .glb / .gltf (the per-vertex `_CLUSTER` attribute and COLOR_0, vertices split per
    cluster) or .obj (a group `g cluster_K` before each run of faces of cluster K).
    Raises mlclust.Error (INVALID_ARGUMENT for a label count other than one per face)."""
    v = np.ascontiguousarray(vertices, dtype=np.float32)
    f = np.ascontiguousarray(faces, dtype=np.uint32)
    l = np.ascontiguousarray(labels, dtype=np.int64)
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
        raise ValueError("vertices and faces must have shapes (V, 3) and (F, 3)")
    if l.shape != (f.shape[0],):
        raise ValueError(f"one label per face is needed: {l.shape[0] if l.ndim else 0} labels "
                         f"for {f.shape[0]} faces")
    error = ctypes.create_string_buffer(2048)
    code = _draco._library().mlclust_write_clustered(
        os.fsencode(path), v.ctypes.data, v.shape[0], f.ctypes.data, f.shape[0], l.ctypes.data,
        error, len(error))
    if code != 0:
        _fail(code, error)
