"""Draco encoding and mesh files through libmlclust_draco_c (core/io behind a C ABI).

Debian has no Python Draco; the shared library is built with the package
(python/CMakeLists.txt) and sits beside this file, or where MLCLUST_DRACO_LIB says.
"""

import ctypes
import os

import numpy as np

_LIB = None

METHODS = {"sequential": 0, "edgebreaker": 1}


def _library():
    global _LIB
    if _LIB is None:
        path = os.environ.get("MLCLUST_DRACO_LIB") or os.path.join(
            os.path.dirname(os.path.abspath(__file__)), "libmlclust_draco_c.so")
        try:
            lib = ctypes.CDLL(path)
        except OSError as e:
            raise ImportError(
                f"mlclust: cannot load the Draco encoder {path} ({e}); build the "
                "mlclust_python target, or set MLCLUST_DRACO_LIB") from e
        lib.mlclust_draco_encode.restype = ctypes.c_int
        lib.mlclust_draco_encode.argtypes = [
            ctypes.c_void_p, ctypes.c_uint64, ctypes.c_void_p, ctypes.c_uint64,
            ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_int,
            ctypes.POINTER(ctypes.c_void_p), ctypes.POINTER(ctypes.c_uint64),
            ctypes.c_char_p, ctypes.c_uint64]
        lib.mlclust_draco_free.restype = None
        lib.mlclust_draco_free.argtypes = [ctypes.c_void_p]
        lib.mlclust_read_mesh.restype = ctypes.c_int
        lib.mlclust_read_mesh.argtypes = [
            ctypes.c_char_p, ctypes.POINTER(ctypes.c_void_p), ctypes.POINTER(ctypes.c_uint64),
            ctypes.POINTER(ctypes.c_void_p), ctypes.POINTER(ctypes.c_uint64),
            ctypes.c_char_p, ctypes.c_uint64]
        lib.mlclust_write_clustered.restype = ctypes.c_int
        lib.mlclust_write_clustered.argtypes = [
            ctypes.c_char_p, ctypes.c_void_p, ctypes.c_uint64, ctypes.c_void_p,
            ctypes.c_uint64, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_uint64]
        _LIB = lib
    return _LIB


def encode_mesh(vertices, faces, quantization_bits=0, speed=5, method="sequential",
                face_ids=False):
    """Encodes a triangle mesh as Draco bytes.

    vertices: (V, 3) array-like of float32-convertible coordinates.
    faces: (F, 3) array-like of vertex indices (0..V-1).
    method "sequential" keeps face and vertex order exactly; "edgebreaker" is several
    times smaller but reorders faces, so use it with face_ids=True (the server then
    restores the order). quantization_bits 0 keeps positions bit for bit.
    Returns (bytes, status_code, message): status_code 0 on success, else an
    absl/gRPC status code number and the encoder's message.
    """
    v = np.ascontiguousarray(vertices, dtype=np.float32)
    f = np.ascontiguousarray(faces)
    if v.ndim != 2 or v.shape[1] != 3:
        return None, 3, f"vertices must have shape (V, 3), got {v.shape}"
    if f.ndim != 2 or f.shape[1] != 3:
        return None, 3, f"faces must have shape (F, 3), got {f.shape}"
    if f.size and (not np.issubdtype(f.dtype, np.integer) or f.min() < 0):
        return None, 3, "faces must hold non-negative integer vertex indices"
    if f.size and f.max() > np.iinfo(np.uint32).max:
        return None, 3, "a face index does not fit 32 bits"
    f = np.ascontiguousarray(f, dtype=np.uint32)
    if method not in METHODS:
        return None, 3, f"method must be one of {sorted(METHODS)}, got {method!r}"
    lib = _library()
    out = ctypes.c_void_p()
    size = ctypes.c_uint64()
    error = ctypes.create_string_buffer(1024)
    code = lib.mlclust_draco_encode(
        v.ctypes.data, v.shape[0], f.ctypes.data, f.shape[0], int(quantization_bits),
        int(speed), METHODS[method], 1 if face_ids else 0, ctypes.byref(out),
        ctypes.byref(size), error, len(error))
    if code != 0:
        return None, code, error.value.decode("utf-8", "replace")
    try:
        return ctypes.string_at(out.value, size.value), 0, ""
    finally:
        lib.mlclust_draco_free(out)
