"""A client for the mlclust gRPC service (proto/mlclust/v1/mlclust.proto)."""

import sys
from typing import Callable, NamedTuple, Optional

import grpc
import numpy as np

from . import _draco
from .hierarchy import Hierarchy
from .v1 import mlclust_pb2 as pb
from .v1 import mlclust_pb2_grpc as pb_grpc

ALGORITHMS = {
    "hc": pb.ALGORITHM_HC, "ml": pb.ALGORITHM_ML, "pml": pb.ALGORITHM_PML,
    "emlo": pb.ALGORITHM_EMLO, "bb": pb.ALGORITHM_BB, "vsa": pb.ALGORITHM_VSA,
    "lnkmeans": pb.ALGORITHM_LN_KMEANS, "kmeans": pb.ALGORITHM_KMEANS,
}
ENERGIES = {
    "cvd": pb.ENERGY_CVD, "cvd-adaptive": pb.ENERGY_CVD_ADAPTIVE,
    "mwcvd-area": pb.ENERGY_MWCVD_AREA, "mwcvd-variance": pb.ENERGY_MWCVD_VARIANCE,
    "mwcvd-max": pb.ENERGY_MWCVD_MAX, "planar": pb.ENERGY_PLANAR,
    "sphere": pb.ENERGY_SPHERE, "variance": pb.ENERGY_VARIANCE,
}
_CODES = {code.value[0]: code for code in grpc.StatusCode}


class Error(Exception):
    """A failed job or call: `code` is a grpc.StatusCode, `details` the server's message
    (what is wrong and where)."""

    def __init__(self, code, details):
        self.code = code if isinstance(code, grpc.StatusCode) else _CODES.get(
            code, grpc.StatusCode.UNKNOWN)
        self.details = details
        super().__init__(f"{self.code.name}: {details}")


class Progress(NamedTuple):
    """What a progress callback receives, on every event before the levels are complete."""
    stage: str                # "queued", "decode", "measures", "cluster", "levels", ...
    fraction: float           # 0..1 where the server knows it, else 0
    message: str
    levels_received: int
    cluster_count: int        # of the last level received (0 before the first)
    queue_position: int       # jobs ahead when accepted


class _Assembler:
    """Collects one job's events into a Hierarchy, checking the stream is consistent."""

    def __init__(self, progress):
        self._progress = progress
        self._pieces = []
        self._have = 0
        self._total = None
        self._started = False
        self._counts, self._energies, self._sources, self._ends = [], [], [], []
        self._element, self._to, self._from = [], [], []
        self._triplets = 0
        self.job_id = ""
        self.queue_position = 0
        self.done = None
        self.failed = None
        self._stage, self._fraction, self._message = "", 0.0, ""

    def add(self, event):
        kind = event.WhichOneof("event")
        if kind == "accepted":
            self.job_id = event.accepted.job_id
            self.queue_position = event.accepted.queue_position
            self._stage = "queued"
        elif kind == "progress":
            p = event.progress
            self._stage, self._fraction, self._message = p.stage, p.fraction, p.message
        elif kind == "snapshot":
            self._snapshot(event.snapshot)
            self._stage = "levels"
        elif kind == "levels":
            self._levels(event.levels)
            self._stage = "levels"
        elif kind == "done":
            self.done = event.done
        elif kind == "failed":
            self.failed = event.failed
        if self._progress is not None and kind not in ("done", "failed"):
            self._progress(Progress(self._stage, self._fraction, self._message,
                                    len(self._counts),
                                    self._counts[-1] if self._counts else 0,
                                    self.queue_position))

    def _snapshot(self, s):
        if self._started:
            raise Error(grpc.StatusCode.DATA_LOSS, "a snapshot after the hierarchy had started")
        if s.first_element != self._have:
            raise Error(grpc.StatusCode.DATA_LOSS,
                        f"snapshot piece starts at element {s.first_element}, expected {self._have}")
        piece = np.array(s.labels, dtype=np.uint32)
        self._pieces.append(piece)
        self._have += piece.size
        if self._have > s.total_elements:
            raise Error(grpc.StatusCode.DATA_LOSS, "snapshot holds more labels than its total_elements")
        if self._have == s.total_elements:
            self._started = True
            self._counts.append(s.cluster_count)
            self._energies.append(s.energy)
            self._sources.append(s.level)
            self._ends.append(0)

    def _levels(self, b):
        if not self._started:
            raise Error(grpc.StatusCode.DATA_LOSS, "levels arrived before the snapshot")
        n = len(b.cluster_count)
        if len(b.energy) != n or len(b.triplet_end) != n:
            raise Error(grpc.StatusCode.DATA_LOSS, "a level batch with arrays of different lengths")
        if b.first_level != len(self._counts):
            raise Error(grpc.StatusCode.DATA_LOSS,
                        f"levels from {b.first_level} arrived, expected level {len(self._counts)}")
        m = len(b.element)
        if len(b.to_cluster) != m or len(b.from_cluster) != m:
            raise Error(grpc.StatusCode.DATA_LOSS,
                        "a level batch with triplet arrays of different lengths")
        ends = np.array(b.triplet_end, dtype=np.int64)
        if n and (np.any(np.diff(ends) < 0) or ends[0] < 0 or ends[-1] > m):
            raise Error(grpc.StatusCode.DATA_LOSS, "a level batch with triplet_end out of order")
        element = np.array(b.element, dtype=np.uint32)
        if element.size and int(element.max()) >= self._have:
            raise Error(grpc.StatusCode.DATA_LOSS,
                        f"a triplet names element {int(element.max())} of {self._have}")
        self._element.append(element)
        self._to.append(np.array(b.to_cluster, dtype=np.uint32))
        self._from.append(np.array(b.from_cluster, dtype=np.uint32))
        self._counts.extend(b.cluster_count)
        self._energies.extend(b.energy)
        sources = list(b.source_level)
        self._sources.extend(sources if len(sources) == n else [-1] * n)
        self._ends.extend((ends + self._triplets).tolist())
        self._triplets += m

    def finish(self):
        if self.done is None:
            raise Error(grpc.StatusCode.DATA_LOSS, "the job ended without a done event")
        if not self._started:
            raise Error(grpc.StatusCode.DATA_LOSS, "the job sent no complete snapshot")
        cat = lambda arrays: (np.concatenate(arrays) if arrays
                              else np.empty(0, dtype=np.uint32))
        return Hierarchy(np.concatenate(self._pieces), self._counts, self._energies,
                         self._sources, self._ends, cat(self._element), cat(self._to),
                         cat(self._from), done=self.done, job_id=self.job_id)


def _option_text(value):
    if isinstance(value, bool):
        return "on" if value else "off"
    return str(value)


class Client:
    """A connection to an mlclust server at "host:port" (plaintext).

    Messages over gRPC's default 4 MiB receive limit are refused as by any default
    client; pass max_receive_message_length=-1 to lift it. `options` are further gRPC
    channel arguments; `credentials` (grpc.ssl_channel_credentials) makes it TLS.
    """

    def __init__(self, address: str, *, max_receive_message_length: Optional[int] = None,
                 options=None, credentials=None):
        channel_options = list(options or [])
        if max_receive_message_length is not None:
            channel_options.append(("grpc.max_receive_message_length",
                                    max_receive_message_length))
        if credentials is None:
            self._channel = grpc.insecure_channel(address, options=channel_options)
        else:
            self._channel = grpc.secure_channel(address, credentials, options=channel_options)
        self._stub = pb_grpc.ClusteringStub(self._channel)

    def close(self):
        self._channel.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def stats(self, timeout: float = 10.0):
        """The server's Stats message (queue depth, job counts, GL device)."""
        try:
            return self._stub.GetStats(pb.GetStatsRequest(), timeout=timeout)
        except grpc.RpcError as e:
            raise Error(e.code(), e.details()) from None

    def cluster_mesh(self, vertices, faces, algo: str = "ml", energy: str = "cvd",
                     clusters: int = 0, *, seed: int = 1, levels=None, device: str = "auto",
                     label: str = "", progress: Optional[Callable[[Progress], None]] = None,
                     timeout: Optional[float] = None, draco=None, batch_triplets: int = 0,
                     chunk_bytes: int = 1 << 20, **options) -> Hierarchy:
        """Clusters a triangle mesh; element ids are face indices (rows of `faces`).

        vertices (V, 3) floats, faces (F, 3) vertex indices. algo: hc, ml, pml (every
        level down to `clusters`, 0 = to one), emlo, bb, vsa (one level at `clusters`,
        after the seeding level at the same count). energy: cvd, cvd-adaptive,
        mwcvd-area, mwcvd-variance, mwcvd-max, planar, sphere. levels=(k_high, k_low)
        sends only those levels (a snapshot at the first). Algorithm and energy options
        by name, '-' written '_' (p_percent=10, guard=False, gamma=1.5, ...).
        draco: how the mesh is compressed for the upload: by default sequential and
        lossless (positions bit for bit); {"method": "edgebreaker",
        "quantization_bits": 14} is several times smaller and writes per-face ids so
        that labels still follow `faces` (positions then arrive quantised).
        Raises Error (with the gRPC status code) on any failure.
        """
        draco = dict(draco or {})
        method = draco.pop("method", "sequential")
        face_ids = draco.pop("face_ids", method == "edgebreaker")
        payload, code, message = _draco.encode_mesh(
            vertices, faces, quantization_bits=draco.pop("quantization_bits", 0),
            speed=draco.pop("speed", 5), method=method, face_ids=face_ids)
        if draco:
            raise ValueError(f"unknown draco settings {sorted(draco)}")
        if code != 0:
            raise Error(code, f"encoding the mesh: {message}")
        spec = self._spec(pb.INPUT_KIND_DRACO_MESH, algo, energy, clusters, seed, levels,
                          device, label, batch_triplets, options)
        return self._run(spec, payload, progress, timeout, chunk_bytes)

    def cluster_points(self, points, algo: str = "ml", clusters: int = 0, *, seed: int = 1,
                       levels=None, device: str = "auto", label: str = "",
                       progress: Optional[Callable[[Progress], None]] = None,
                       timeout: Optional[float] = None, batch_triplets: int = 0,
                       chunk_bytes: int = 1 << 20, **options) -> Hierarchy:
        """Clusters the rows of `points` (m x d); element ids are row indices. Energy:
        the within-cluster sum of squares. algo: ml, pml, hc (levels from the voxel grid,
        grid=A voxels per dimension, down to `clusters`), lnkmeans, kmeans (at
        `clusters`). Options as for cluster_mesh (grid=8, init="kmeans++", ...)."""
        x = np.asarray(points)
        if x.ndim != 2:
            raise ValueError(f"points must be a 2-d array (m x d), got shape {x.shape}")
        payload = np.ascontiguousarray(x, dtype="<f4").tobytes()
        spec = self._spec(pb.INPUT_KIND_POINTS_F32, algo, "variance", clusters, seed, levels,
                          device, label, batch_triplets, options)
        spec.point_dims = x.shape[1]
        return self._run(spec, payload, progress, timeout, chunk_bytes)

    @staticmethod
    def _spec(kind, algo, energy, clusters, seed, levels, device, label, batch_triplets,
              options):
        if algo not in ALGORITHMS:
            raise ValueError(f"algo must be one of {sorted(ALGORITHMS)}, got {algo!r}")
        if energy not in ENERGIES:
            raise ValueError(f"energy must be one of {sorted(ENERGIES)}, got {energy!r}")
        spec = pb.JobSpec(input_kind=kind, algorithm=ALGORITHMS[algo], energy=ENERGIES[energy],
                          clusters=int(clusters), seed=int(seed), device=device, label=label,
                          batch_triplets=int(batch_triplets))
        if levels is not None:
            spec.levels_high, spec.levels_low = (int(levels[0] or 0), int(levels[1] or 0))
        for name, value in options.items():
            spec.options[name.replace("_", "-")] = _option_text(value)
        return spec

    def _run(self, spec, payload, progress, timeout, chunk_bytes):
        spec.input_bytes = len(payload)
        chunk_bytes = max(1, int(chunk_bytes))

        def requests():
            view = memoryview(payload)
            offset = 0
            while True:
                request = pb.RunRequest(chunk=bytes(view[offset:offset + chunk_bytes]))
                if offset == 0:
                    request.spec.CopyFrom(spec)
                yield request
                offset += chunk_bytes
                if offset >= len(payload):
                    return

        call = self._stub.Run(requests(), timeout=timeout)
        assembler = _Assembler(progress)
        try:
            for event in call:
                assembler.add(event)
        except grpc.RpcError as e:
            raise Error(e.code(), e.details()) from None
        except Error:
            call.cancel()
            raise
        if assembler.failed is not None:
            raise Error(assembler.failed.code, assembler.failed.message)
        return assembler.finish()
