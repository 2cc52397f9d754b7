"""A client for the mlclust gRPC service (proto/mlclust/v1/mlclust.proto)."""

import logging
import random
import socket
import sys
import time
import zlib
from concurrent.futures import ThreadPoolExecutor
from typing import Callable, NamedTuple, Optional

import grpc
import numpy as np

from . import _draco, _local, _wire
from .hierarchy import Hierarchy
from .v1 import mlclust_pb2 as pb
from .v1 import mlclust_pb2_grpc as pb_grpc

ALGORITHMS = {
    "hc": pb.ALGORITHM_HC, "ml": pb.ALGORITHM_ML, "pml": pb.ALGORITHM_PML,
    "emlo": pb.ALGORITHM_EMLO, "bb": pb.ALGORITHM_BB, "vsa": pb.ALGORITHM_VSA,
    "lnkmeans": pb.ALGORITHM_LN_KMEANS, "kmeans": pb.ALGORITHM_KMEANS,
    "xmeans": pb.ALGORITHM_XMEANS, "bisecting": pb.ALGORITHM_BISECTING,
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

    def __init__(self, code, details, accepted=False):
        self.code = code if isinstance(code, grpc.StatusCode) else _CODES.get(
            code, grpc.StatusCode.UNKNOWN)
        self.details = details
        # The server had accepted the job (its Accepted event arrived) before it failed.
        self.accepted = accepted
        super().__init__(f"{self.code.name}: {details}")


def _host_port(text):
    """(host, port) of "HOST:PORT" or "[IPv6]:PORT"; ValueError when it is neither."""
    if text.startswith("["):
        host, sep, port = text[1:].partition("]:")
    else:
        host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit() or not 1 <= int(port) <= 65535:
        raise ValueError(f"{text!r} is not HOST:PORT (port 1-65535)")
    return host, port


def resolve_replicas(address):
    """The replicas an address names, each "HOST:PORT": the items of a list or of a
    comma-separated string as written, or every address a "dns:///NAME:PORT" resolves
    to; duplicates removed. None for a single plain address (one server)."""
    if isinstance(address, str):
        if "," not in address and not address.startswith("dns:"):
            return None
        items = address.split(",")
    else:
        items = list(address)
    out = []
    for item in items:
        item = item.strip()
        if not item:
            raise ValueError(f"an empty server address in {address!r}")
        if item.startswith("dns:"):
            name = item[len("dns:"):]
            if name.startswith("//"):
                name = name[2:].partition("/")[2]  # the authority is left to the system's
            host, port = _host_port(name)
            try:
                found = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
            except socket.gaierror as e:
                raise Error(grpc.StatusCode.NOT_FOUND, f"cannot resolve {item} ({e})") from None
            resolved = [f"[{a[4][0]}]:{port}" if a[0] == socket.AF_INET6 else
                        f"{a[4][0]}:{port}" for a in found]
        else:
            _host_port(item)
            resolved = [item]
        for one in resolved:
            if one not in out:
                out.append(one)
    return out


def split_job_id(job_id):
    """(replica, server id) of "HOST:PORT/JOBID", or (None, job_id)."""
    replica, sep, job = job_id.rpartition("/")
    if sep and replica and job:
        try:
            _host_port(replica)
            return replica, job
        except ValueError:
            pass
    return None, job_id


def _is_broken_stream(error):
    """A stream that broke on the way (the connection dropped, a proxy reset it) rather
    than a job or request that failed (the C++ client's IsBrokenStream)."""
    details = error.details or ""
    return (error.code == grpc.StatusCode.UNAVAILABLE
            or (error.code == grpc.StatusCode.INTERNAL and "RST_STREAM" in details)
            or (error.code == grpc.StatusCode.UNKNOWN and "Stream removed" in details))


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

    def __init__(self, progress, absolute_levels=False):
        self._progress = progress
        # Watch numbers levels as the job does: the snapshot's level is the first.
        self._absolute_levels = absolute_levels
        self._offset = 0
        self._pieces = []
        self._have = 0
        self._total = None
        self._started = False
        # Per level, in pieces (one numpy array per batch) joined at the end.
        self._counts, self._energies, self._sources, self._ends = [], [], [], []
        self._num_levels = 0
        self._last_count = 0
        self._element, self._to, self._from = [], [], []
        self._triplets = 0
        self._continuing = False  # the last level received continues in the next batch
        self.job_id = ""
        self.queue_position = 0
        self.done = None
        self.failed = None
        self._stage, self._fraction, self._message = "", 0.0, ""

    def add_bytes(self, data):
        """One JobEvent as its wire bytes: level batches and snapshots by the numpy fast
        path (_wire), everything else through the protobuf runtime."""
        parsed = _wire.parse_bulk_event(data)
        if parsed is None:
            self.add(pb.JobEvent.FromString(data))
        elif parsed[0] == "levels":
            self._levels(**parsed[1])
            self._report("levels")
        else:
            self._snapshot(**parsed[1])
            self._report("snapshot")

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
            s = event.snapshot
            self._snapshot(s.level, s.cluster_count, s.energy, np.array(s.labels, dtype=np.uint32),
                           s.first_element, s.total_elements)
        elif kind == "levels":
            b = event.levels
            triplets = (b.element, b.to_cluster, b.from_cluster)
            if b.packed_element or b.packed_to_cluster or b.packed_from_cluster:
                # JobSpec.packed_triplets: raw little-endian uint32 instead of varints.
                if len(b.element) or len(b.to_cluster) or len(b.from_cluster):
                    raise Error(grpc.StatusCode.DATA_LOSS,
                                "a level batch with both packed and repeated triplets")
                if any(len(a) % 4 for a in (b.packed_element, b.packed_to_cluster,
                                            b.packed_from_cluster)):
                    raise Error(grpc.StatusCode.DATA_LOSS,
                                "a packed triplet array whose length is not a multiple of 4")
                triplets = tuple(np.frombuffer(a, dtype="<u4") for a in (
                    b.packed_element, b.packed_to_cluster, b.packed_from_cluster))
            self._levels(b.first_level, *(np.array(a, dtype=t) for a, t in (
                (b.cluster_count, np.uint32), (b.energy, np.float64), (b.triplet_end, np.uint32),
                (triplets[0], np.uint32), (triplets[1], np.uint32), (triplets[2], np.uint32),
                (b.source_level, np.uint32))), last_level_continues=b.last_level_continues)
        elif kind == "done":
            self.done = event.done
        elif kind == "failed":
            self.failed = event.failed
        self._report(kind)

    def _report(self, kind):
        if kind in ("snapshot", "levels"):
            self._stage = "levels"
        if self._progress is not None and kind not in ("done", "failed"):
            self._progress(Progress(self._stage, self._fraction, self._message,
                                    self._num_levels, self._last_count,
                                    self.queue_position))

    def _snapshot(self, level, cluster_count, energy, labels, first_element, total_elements):
        if self._started:
            raise Error(grpc.StatusCode.DATA_LOSS, "a snapshot after the hierarchy had started")
        if first_element != self._have:
            raise Error(grpc.StatusCode.DATA_LOSS,
                        f"snapshot piece starts at element {first_element}, expected {self._have}")
        self._pieces.append(labels)
        self._have += labels.size
        if self._have > total_elements:
            raise Error(grpc.StatusCode.DATA_LOSS, "snapshot holds more labels than its total_elements")
        if self._have == total_elements:
            self._started = True
            if self._absolute_levels:
                self._offset = int(level)
            self._counts.append(np.array([cluster_count], dtype=np.int64))
            self._energies.append(np.array([energy], dtype=np.float64))
            self._sources.append(np.array([level], dtype=np.int64))
            self._ends.append(np.zeros(1, dtype=np.int64))
            self._num_levels = 1
            self._last_count = cluster_count

    def _levels(self, first_level, cluster_count, energy, triplet_end, element, to_cluster,
                from_cluster, source_level, last_level_continues=False):
        if not self._started:
            raise Error(grpc.StatusCode.DATA_LOSS, "levels arrived before the snapshot")
        first_level -= self._offset
        n = len(cluster_count)
        if len(energy) != n or len(triplet_end) != n:
            raise Error(grpc.StatusCode.DATA_LOSS, "a level batch with arrays of different lengths")
        # A level too big for one message continues in the next batch, which starts at the
        # same level (LevelBatch.last_level_continues): its triplets extend that level.
        continued = self._continuing
        expected = self._num_levels - 1 if continued else self._num_levels
        if first_level != expected or (continued and n == 0):
            raise Error(grpc.StatusCode.DATA_LOSS,
                        f"levels from {first_level} arrived, expected level {expected}")
        if continued and int(cluster_count[0]) != self._last_count:
            raise Error(grpc.StatusCode.DATA_LOSS,
                        f"level {first_level} continued with another cluster count")
        m = len(element)
        if len(to_cluster) != m or len(from_cluster) != m:
            raise Error(grpc.StatusCode.DATA_LOSS,
                        "a level batch with triplet arrays of different lengths")
        ends = triplet_end.astype(np.int64)
        if n and (np.any(np.diff(ends) < 0) or ends[0] < 0 or ends[-1] > m):
            raise Error(grpc.StatusCode.DATA_LOSS, "a level batch with triplet_end out of order")
        if m and int(element.max()) >= self._have:
            raise Error(grpc.StatusCode.DATA_LOSS,
                        f"a triplet names element {int(element.max())} of {self._have}")
        self._element.append(element)
        self._to.append(to_cluster)
        self._from.append(from_cluster)
        sources = (source_level.astype(np.int64) if len(source_level) == n
                   else np.full(n, -1, dtype=np.int64))
        ends = ends + self._triplets
        first = 0
        if continued:
            self._ends[-1] = self._ends[-1].copy()
            self._ends[-1][-1] = ends[0]
            first = 1
        self._counts.append(cluster_count[first:].astype(np.int64))
        self._energies.append(energy[first:].astype(np.float64))
        self._sources.append(sources[first:])
        self._ends.append(ends[first:])
        self._triplets += m
        self._num_levels += n - first
        if n:
            self._last_count = int(cluster_count[-1])
        if n:
            self._continuing = bool(last_level_continues)

    @property
    def started(self):
        """The snapshot is complete (levels may follow)."""
        return self._started

    def last_complete_level(self):
        """The job's number of the last complete level held (a level split across
        batches counts once its last piece arrived)."""
        return self._offset + self._num_levels - 1 - (1 if self._continuing else 0)

    def drop_partial_level(self):
        """A stream broke: a level split across batches and not yet complete is dropped
        (the resumed stream sends it again whole)."""
        if not self._continuing:
            return
        keep = self._num_levels - 1
        ends = np.concatenate(self._ends)
        cut = int(ends[keep - 1])
        for name in ("_element", "_to", "_from"):
            arrays = getattr(self, name)
            joined = np.concatenate(arrays) if arrays else np.empty(0, dtype=np.uint32)
            setattr(self, name, [joined[:cut]])
        for name in ("_counts", "_energies", "_sources"):
            setattr(self, name, [np.concatenate(getattr(self, name))[:keep]])
        self._ends = [ends[:keep]]
        self._triplets = cut
        self._num_levels = keep
        self._last_count = int(self._counts[0][-1])
        self._continuing = False

    @property
    def final(self):
        """The stream carried the job's final event (done or failed)."""
        return self.done is not None or self.failed is not None

    def held(self):
        """(start labels, cluster counts, energies, triplet ends, element, to, from) of the
        complete levels received, or None before the snapshot was complete."""
        if not self._started:
            return None
        keep = self._num_levels - (1 if self._continuing else 0)
        ends = np.concatenate(self._ends)[:keep]
        cut = int(ends[-1])
        cat = lambda arrays: (np.concatenate(arrays)[:cut] if arrays
                              else np.empty(0, dtype=np.uint32))
        return (np.concatenate(self._pieces), np.concatenate(self._counts)[:keep],
                np.concatenate(self._energies)[:keep], ends, cat(self._element),
                cat(self._to), cat(self._from))

    def finish(self):
        if self.done is None:
            raise Error(grpc.StatusCode.DATA_LOSS, "the job ended without a done event")
        if self._continuing:
            raise Error(grpc.StatusCode.DATA_LOSS, "the job ended inside a split level")
        if not self._started:
            raise Error(grpc.StatusCode.DATA_LOSS, "the job sent no complete snapshot")
        cat = lambda arrays: (np.concatenate(arrays) if arrays
                              else np.empty(0, dtype=np.uint32))
        return Hierarchy(np.concatenate(self._pieces), np.concatenate(self._counts),
                         np.concatenate(self._energies), np.concatenate(self._sources),
                         np.concatenate(self._ends), cat(self._element), cat(self._to),
                         cat(self._from), done=self.done, job_id=self.job_id)


def _levels_held(held):
    return 0 if held is None else len(held[1])


def _same_levels(kept, new):
    """Checks that two streams of one job (a lost replica's and the one it was submitted
    to again) agree on the levels both hold: the same start, cluster counts, energies and
    triplets. Returns the one holding more levels; Error DATA_LOSS naming the first level
    that differs."""
    if kept is None or new is None:
        return new if kept is None else kept
    n = min(_levels_held(kept), _levels_held(new))
    def differs(level, how):
        return Error(grpc.StatusCode.DATA_LOSS,
                     f"the job was run again on another replica and its level {level} differs "
                     f"from the one received before ({how}): the replicas do not compute the "
                     "same levels (different builds, versions or devices: a GPU replica's "
                     "float order may differ from a CPU one's?)")
    if not np.array_equal(kept[0], new[0]):
        raise differs(0, "its start labels differ")
    for level in range(n):
        if kept[1][level] != new[1][level] or kept[2][level] != new[2][level]:
            raise differs(level, f"it has {new[1][level]} clusters (energy {new[2][level]}), "
                          f"the level held {kept[1][level]} (energy {kept[2][level]})")
        a, b = (int(kept[3][level - 1]) if level else 0), int(kept[3][level])
        c, d = (int(new[3][level - 1]) if level else 0), int(new[3][level])
        if any(not np.array_equal(x[a:b], y[c:d]) for x, y in zip(kept[4:], new[4:])):
            raise differs(level, "its triplets differ")
    return kept if _levels_held(kept) >= _levels_held(new) else new


def _lost_replica(error, final):
    """A replica that accepted the job was lost (it died, was drained with the job, or the
    stream broke before the job's final event), rather than the job failing or being
    cancelled there, or the caller's own timeout."""
    return (error.code == grpc.StatusCode.UNAVAILABLE
            or (_is_broken_stream(error) and not final))


def _warn_resubmit(replica, error, attempt, limit, levels_kept):
    logging.getLogger("mlclust").warning(
        "replica %s accepted the job and then became unreachable (%s); submitting it again "
        "to the next replica (try %d of %d), keeping the %d levels received", replica,
        error.details, attempt, limit, levels_kept)


def _option_text(value):
    if isinstance(value, bool):
        return "on" if value else "off"
    return str(value)


class Client:
    """A connection to an mlclust server at "host:port" (plaintext), or, with no address,
    to a server of its own.

    Client() starts the bundled `mlclust serve` on a Unix socket in a private folder
    (mode 0700) and stops it with the client: close(), the end of a `with` block, garbage
    collection or interpreter exit (mlclust/_local.py; `serve_args` are further serve
    flags, e.g. ["--workers", "2"]). An address selects a remote server instead.
    Messages over gRPC's default 4 MiB receive limit are refused as by any default
    client; pass max_receive_message_length=-1 to lift it. `options` are further gRPC
    channel arguments; `credentials` (grpc.ssl_channel_credentials) makes it TLS.
    """

    def __init__(self, address=None, *, max_receive_message_length: Optional[int] = None,
                 options=None, credentials=None, spread: str = "least-loaded",
                 resubmit: int = 2, on_resubmit: Optional[Callable[..., None]] = None,
                 serve_args=()):
        self._local = None
        if address is None:
            self._local = _local.LocalServer(serve_args)
            address = self._local.address
        # Several servers (replicas): a list of "host:port", a comma-separated string, or
        # "dns:///name:port". Jobs go to the least loaded replica (GetStats: queue depth
        # plus running jobs; ties at random) or, with spread="in-order", in the order
        # given; a replica unreachable, draining or full BEFORE it accepted the job is
        # skipped and the next tried. A replica lost AFTER accepting a job (UNAVAILABLE:
        # it died, or was drained with the job; or the stream broke before the job's final
        # event) loses no job: it is submitted again to the next replica, at most
        # `resubmit` times (0: never), on_resubmit(replica, error, attempt, resubmit,
        # levels_kept) called before each (by default a warning on the "mlclust" logger).
        # A job is a pure function of its input and options (seed included): the levels
        # already received are kept, and the new stream's repeats are checked against them
        # (Error DATA_LOSS if a replica sent other levels) and not reported twice. A job
        # that failed or was cancelled on its replica, or hit `timeout`, is not submitted
        # again. A detached job's id names its replica ("host:port/JOBID"); watch and
        # cancel go there; replicas share nothing, so a detached job lost with its replica
        # is gone: watch(job_id, resubmit=...) submits it again (the caller keeps what
        # rebuilds it). jobs() lists every replica's, stats() is {replica: Stats}.
        if spread not in ("least-loaded", "in-order"):
            raise ValueError(f"spread must be least-loaded or in-order, got {spread!r}")
        if int(resubmit) < 0:
            raise ValueError(f"resubmit must be >= 0, got {resubmit!r}")
        self._address = address
        self._replicas = resolve_replicas(address)
        self._spread = spread
        self._resubmit = int(resubmit)
        self._on_resubmit = on_resubmit or _warn_resubmit
        self._member_args = dict(max_receive_message_length=max_receive_message_length,
                                 options=options, credentials=credentials)
        self._members = {}
        if self._replicas is not None:
            if not self._replicas:
                raise ValueError("no server address given")
            return
        channel_options = list(options or [])
        if max_receive_message_length is not None:
            channel_options.append(("grpc.max_receive_message_length",
                                    max_receive_message_length))
        if credentials is None:
            self._channel = grpc.insecure_channel(address, options=channel_options)
        else:
            self._channel = grpc.secure_channel(address, credentials, options=channel_options)
        self._stub = pb_grpc.ClusteringStub(self._channel)
        # Run with the events left as bytes, for the assembler's numpy fast path.
        self._run_raw = self._channel.stream_stream(
            "/mlclust.v1.Clustering/Run", request_serializer=pb.RunRequest.SerializeToString,
            response_deserializer=None)
        self._watch_raw = self._channel.unary_stream(
            "/mlclust.v1.Clustering/Watch", request_serializer=pb.WatchRequest.SerializeToString,
            response_deserializer=None)

    def close(self):
        for member in self._members.values():
            member.close()
        if self._replicas is None:
            self._channel.close()
        if self._local is not None:
            self._local.stop()

    @property
    def address(self):
        """The server's address: "unix:..." for the client's own server."""
        return self._address

    # --- several replicas ------------------------------------------------------------
    def _member(self, replica):
        if replica not in self._members:
            self._members[replica] = Client(replica, **self._member_args)
        return self._members[replica]

    def _order(self):
        """The replicas in the order they are tried."""
        if self._spread == "in-order":
            return list(self._replicas)

        def load(replica):
            try:
                stats = self._member(replica).stats(timeout=2.0)
            except Error:
                return None
            if stats.draining:
                return None
            return stats.queue_depth + stats.jobs_running + (1 if stats.job_running else 0)

        for replica in self._replicas:
            self._member(replica)  # created here, not in the threads
        with ThreadPoolExecutor(len(self._replicas)) as pool:
            loads = list(pool.map(load, self._replicas))
        order = list(range(len(self._replicas)))
        random.shuffle(order)
        order.sort(key=lambda i: float("inf") if loads[i] is None else loads[i])
        return [self._replicas[i] for i in order]

    def _route(self, job_id):
        """(client, server id, replica) for a job id."""
        replica, job = split_job_id(job_id)
        if replica is not None:
            return self._member(replica), job, replica
        if self._replicas is not None:
            raise ValueError(f"job id {job_id!r} does not name its replica; with several "
                             "servers give the id a detached job returned (HOST:PORT/JOBID)")
        return self, job_id, None

    @staticmethod
    def _explain(error, replica, job):
        if error.code == grpc.StatusCode.UNAVAILABLE:
            return Error(error.code, f"replica {replica}, which holds job {job}, does not "
                         "answer: it was stopped or died, and its jobs and their results went "
                         "with it (replicas share nothing). Submit the job again, from its "
                         "input and options: its levels are the same (watch(job_id, "
                         f"resubmit=...) does it) ({error.details})")
        return Error(error.code, f"replica {replica}: {error.details}")

    def _order_after_loss(self, lost):
        """The replicas to try after `lost` lost a job: a fresh order, the lost one last
        (it may have been restarted at its address)."""
        order = self._order()
        return [r for r in order if r != lost] + [r for r in order if r == lost]

    def _run_on_replicas(self, spec, payload, progress, timeout, chunk_bytes):
        deadline = None if timeout is None else time.monotonic() + timeout
        refused, lost = [], []
        kept = None  # the complete levels received, over the replicas tried
        order, next_ = self._order(), 0
        while True:
            if next_ == len(order):
                if lost:
                    raise Error(grpc.StatusCode.UNAVAILABLE,
                                f"the job was lost with replica {', then '.join(lost)}, and "
                                "no replica accepted it again: " + "; ".join(refused))
                raise Error(grpc.StatusCode.UNAVAILABLE,
                            "no replica accepted the job: " + "; ".join(refused))
            replica = order[next_]
            next_ += 1
            left = None if deadline is None else max(0.0, deadline - time.monotonic())
            kept_levels = _levels_held(kept)

            def report(p, kept_levels=kept_levels):
                # The levels a lost replica had sent come again first: not reported twice.
                if progress is not None and (p.stage != "levels"
                                             or p.levels_received > kept_levels):
                    progress(p)

            assembler = _Assembler(report)
            try:
                result = self._member(replica)._run(spec, payload, report, left,
                                                    chunk_bytes, assembler=assembler)
            except Error as e:
                if e.accepted:
                    kept = _same_levels(kept, assembler.held())
                    if not _lost_replica(e, assembler.final):
                        raise Error(e.code, f"replica {replica}: {e.details}",
                                    accepted=True) from None
                    lost.append(f"{replica} ({e.details})")
                    if len(lost) > self._resubmit:
                        raise Error(e.code, f"replica {replica} accepted the job and then "
                                    f"became unreachable ({e.details}); the job was submitted "
                                    f"again {len(lost) - 1} times, the limit (resubmit="
                                    f"{self._resubmit}): lost with replica "
                                    f"{', then '.join(lost)}", accepted=True) from None
                    self._on_resubmit(replica, e, len(lost), self._resubmit,
                                      _levels_held(kept))
                    order, next_, refused = self._order_after_loss(replica), 0, []
                    continue
                if e.code not in (grpc.StatusCode.UNAVAILABLE,
                                  grpc.StatusCode.RESOURCE_EXHAUSTED):
                    raise Error(e.code, f"replica {replica}: {e.details}") from None
                refused.append(f"{replica} ({e.details})")
                continue
            if spec.detach:
                return f"{replica}/{result}"
            _same_levels(kept, assembler.held())
            result.job_id = f"{replica}/{result.job_id}"
            return result

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def watch(self, job_id: str, from_level: int = 0, *,
              progress: Optional[Callable[[Progress], None]] = None,
              timeout: Optional[float] = None, max_resumes: int = 5,
              resume_delay: float = 0.5,
              on_resume: Optional[Callable[["Error"], None]] = None,
              resubmit: Optional[Callable[[], str]] = None,
              _assembler=None) -> Hierarchy:
        """The levels of a job (detached or not) of this client's tenant, while it runs or
        after it ended: level `from_level` of the job (as a snapshot, the returned
        hierarchy's first level) and every level after it. A stream that breaks on the way
        (UNAVAILABLE, a reset connection) is resumed after the last complete level received
        (WatchRequest.resume), as the C++ client does: at most `max_resumes` times in a row
        without progress, `resume_delay` seconds apart, calling `on_resume(error)` before
        each. `timeout` bounds the whole watch. Raises Error: NOT_FOUND once the server
        dropped the job's results (the details say when and why), PERMISSION_DENIED for
        another tenant's job. The job runs on if this ends.

        Several replicas share nothing: a detached job lost with its replica (UNAVAILABLE
        after the resumes, before its final event) is gone there. `resubmit`, a callable
        that submits the job again (detached) and returns its new id (for example
        lambda: client.cluster_mesh(vertices, faces, ..., detach=True): the caller keeps
        what rebuilds the job), is then called, at most the client's `resubmit` times, and
        the new id watched, the levels received kept and checked as for a run; the
        returned hierarchy's job_id is the id that finished."""
        client, job, replica = self._route(job_id)
        if client is not self:
            return self._watch_on_replica(client, job_id, job, replica, from_level,
                                          progress, timeout, max_resumes, resume_delay,
                                          on_resume, resubmit)
        deadline = None if timeout is None else time.monotonic() + timeout
        assembler = _Assembler(progress, absolute_levels=True)
        if _assembler is not None:
            _assembler.append(assembler)  # the caller keeps the levels if this fails
        resumes = 0
        while True:
            if assembler.started:
                # Resume where the stream stopped: no snapshot, the levels after the last
                # complete one.
                request = pb.WatchRequest(job_id=job_id, resume=True,
                                          from_level=assembler.last_complete_level())
            else:
                request = pb.WatchRequest(job_id=job_id, from_level=int(from_level))
            left = None if deadline is None else max(0.0, deadline - time.monotonic())
            call = self._watch_raw(request, timeout=left)
            progressed = False
            try:
                for event in call:
                    progressed = True
                    assembler.add_bytes(event)
            except grpc.RpcError as e:
                error = Error(e.code(), e.details())
                final = assembler.done is not None or assembler.failed is not None
                if (final or not _is_broken_stream(error)
                        or (deadline is not None
                            and time.monotonic() + resume_delay >= deadline)):
                    raise error from None
                if progressed:
                    resumes = 0
                resumes += 1
                if resumes > max_resumes:
                    raise error from None
                if on_resume is not None:
                    on_resume(error)
                assembler.drop_partial_level()
                if not assembler.started:
                    # The snapshot was cut short: start again from it.
                    assembler = _Assembler(progress, absolute_levels=True)
                    if _assembler is not None:
                        _assembler[-1] = assembler
                time.sleep(resume_delay)
                continue
            except BaseException:
                call.cancel()
                raise
            break
        if assembler.failed is not None:
            raise Error(assembler.failed.code, assembler.failed.message)
        assembler.job_id = job_id
        return assembler.finish()

    def _watch_on_replica(self, client, job_id, job, replica, from_level, progress, timeout,
                          max_resumes, resume_delay, on_resume, resubmit):
        """watch() of "HOST:PORT/JOBID" on its replica; with `resubmit`, a lost replica's
        job submitted again and watched on its new replica."""
        deadline = None if timeout is None else time.monotonic() + timeout
        kept, resubmits = None, 0
        while True:
            kept_levels = _levels_held(kept)

            def report(p, kept_levels=kept_levels):
                if progress is not None and (p.stage != "levels"
                                             or p.levels_received > kept_levels):
                    progress(p)

            left = None if deadline is None else max(0.0, deadline - time.monotonic())
            streams = []
            try:
                hierarchy = client.watch(job, from_level, progress=report, timeout=left,
                                         max_resumes=max_resumes, resume_delay=resume_delay,
                                         on_resume=on_resume, _assembler=streams)
            except Error as e:
                final = bool(streams) and streams[-1].final
                if streams:
                    kept = _same_levels(kept, streams[-1].held())
                if resubmit is None or not _lost_replica(e, final):
                    raise self._explain(e, replica, job) from None
                if resubmits == self._resubmit:
                    raise Error(e.code, f"replica {replica}, which holds job {job}, does not "
                                f"answer ({e.details}); the job was submitted again "
                                f"{resubmits} times, the limit (resubmit={self._resubmit})"
                                ) from None
                resubmits += 1
                self._on_resubmit(replica, e, resubmits, self._resubmit, _levels_held(kept))
                job_id = resubmit()
                client, job, replica = self._route(job_id)
                if client is self:
                    raise ValueError(f"resubmit() returned {job_id!r}, an id without its "
                                     "replica (HOST:PORT/JOBID)") from None
                continue
            _same_levels(kept, streams[-1].held() if streams else None)
            hierarchy.job_id = job_id
            return hierarchy

    def cancel(self, job_id: str, timeout: float = 30.0) -> str:
        """Cancels a queued or running job; returns its state after the call."""
        client, job, replica = self._route(job_id)
        if client is not self:
            try:
                return client.cancel(job, timeout)
            except Error as e:
                raise self._explain(e, replica, job) from None
        try:
            return self._stub.Cancel(pb.CancelRequest(job_id=job_id), timeout=timeout).state
        except grpc.RpcError as e:
            raise Error(e.code(), e.details()) from None

    def jobs(self, timeout: float = 30.0):
        """This tenant's jobs on the server (JobSummary messages: job_id, state, levels,
        seconds_queued, seconds_running, ...), in submission order. With several
        replicas: every replica's that answers, ids "HOST:PORT/JOBID"; Error UNAVAILABLE
        when none answers."""
        if self._replicas is not None:
            out, answered = [], False
            for replica in self._replicas:
                try:
                    jobs = self._member(replica).jobs(timeout)
                except Error:
                    continue
                answered = True
                for job in jobs:
                    job.job_id = f"{replica}/{job.job_id}"
                    out.append(job)
            if not answered:
                raise Error(grpc.StatusCode.UNAVAILABLE, "no replica answered ListJobs")
            return out
        try:
            return list(self._stub.ListJobs(pb.ListJobsRequest(), timeout=timeout).jobs)
        except grpc.RpcError as e:
            raise Error(e.code(), e.details()) from None

    def stats(self, timeout: float = 10.0):
        """The server's Stats message (queue depth, job counts, GL device). With several
        replicas: {replica: Stats, or the Error it answered}."""
        if self._replicas is not None:
            out = {}
            for replica in self._replicas:
                try:
                    out[replica] = self._member(replica).stats(timeout)
                except Error as e:
                    out[replica] = e
            return out
        try:
            return self._stub.GetStats(pb.GetStatsRequest(), timeout=timeout)
        except grpc.RpcError as e:
            raise Error(e.code(), e.details()) from None

    def info(self, timeout: float = 10.0):
        """The server's ServerInfo message (version, build, device, limits, algorithms)."""
        try:
            return self._stub.GetServerInfo(pb.GetServerInfoRequest(), timeout=timeout)
        except grpc.RpcError as e:
            raise Error(e.code(), e.details()) from None

    def cluster_mesh(self, vertices, faces, algo: str = "ml", energy: str = "cvd",
                     clusters: int = 0, *, seed: int = 1, levels=None, device: str = "auto",
                     label: str = "", progress: Optional[Callable[[Progress], None]] = None,
                     timeout: Optional[float] = None, draco=None, batch_triplets: int = 0,
                     chunk_bytes: int = 1 << 20, detach: bool = False, polygons=None,
                     **options):
        """Clusters a triangle mesh; element ids are face indices (rows of `faces`).

        vertices (V, 3) floats, faces (F, 3) vertex indices. algo: hc, ml, pml (every
        level down to `clusters`, 0 = to one), emlo, bb, vsa (one level at `clusters`,
        after the seeding level at the same count). energy: cvd, cvd-adaptive,
        mwcvd-area, mwcvd-variance, mwcvd-max, planar, sphere. levels=(k_high, k_low)
        sends only those levels (a snapshot at the first). progress(Progress) is called
        on every event until the levels are complete; if it raises, the job is cancelled
        and the exception propagates. timeout (seconds) cancels the job when it passes.
        Algorithm and energy options by name, '-' written '_' (p_percent=10,
        guard=False, gamma=1.5, ...); preset="dissertation" runs the text's variant of
        every default that is ours (`mlclust help` marks them), options given still win.
        draco: how the mesh is compressed for the upload: by default sequential and
        lossless (positions bit for bit); {"method": "edgebreaker",
        "quantization_bits": 14} is several times smaller and writes per-face ids so
        that labels still follow `faces` (positions then arrive quantised).
        detach=True returns the job's id (a str) once the server has queued it; the job
        runs on and `watch(job_id)` reads its levels, from this client or any other.
        polygons: for a quad / n-gon mesh triangulated in place (read_mesh does), the
        number of triangles of each polygon in face order (an n-gon is n - 2 consecutive
        rows of `faces`); algo ml, hc, pml, emlo or bb then cluster whole polygons (ours,
        JobSpec.polygon_triangle_counts): no level splits a polygon. Labels stay per face;
        labels_per_polygon(labels, polygons) gives one per polygon.
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
        if polygons is not None:
            counts = np.asarray(polygons).reshape(-1)
            if counts.size and (counts.min() < 0 or counts.max() > 0xFFFFFFFF):
                raise ValueError("polygons: triangle counts must be in [0, 2^32)")
            spec.polygon_triangle_counts.extend(int(c) for c in counts)
        spec.detach = bool(detach)
        return self._run(spec, payload, progress, timeout, chunk_bytes)

    def cluster_points(self, points, algo: str = "ml", clusters: int = 0, *, seed: int = 1,
                       levels=None, device: str = "auto", label: str = "",
                       progress: Optional[Callable[[Progress], None]] = None,
                       timeout: Optional[float] = None, batch_triplets: int = 0,
                       chunk_bytes: int = 1 << 20, detach: bool = False, **options):
        """Clusters the rows of `points` (m x d); element ids are row indices. Energy:
        the within-cluster sum of squares. algo: ml, pml, hc (levels from the voxel grid,
        grid=A voxels per dimension, down to `clusters`), lnkmeans, kmeans (at
        `clusters`), xmeans (from k_min = `clusters`; the last level has the K it found,
        kmax=...), bisecting (levels from `clusters` down to one). Options as for
        cluster_mesh (grid=8, init="kmeans++", ...; preset="dissertation" needs grid >= 1
        where the voxel start runs: the text has no automatic grid)."""
        x = np.asarray(points)
        if x.ndim != 2:
            raise ValueError(f"points must be a 2-d array (m x d), got shape {x.shape}")
        payload = np.ascontiguousarray(x, dtype="<f4").tobytes()
        spec = self._spec(pb.INPUT_KIND_POINTS_F32, algo, "variance", clusters, seed, levels,
                          device, label, batch_triplets, options)
        spec.point_dims = x.shape[1]
        spec.detach = bool(detach)
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
        # Raw uint32 triplets (issue 13) where the server has them; older servers ignore it.
        if "packed_triplets" in pb.JobSpec.DESCRIPTOR.fields_by_name:
            spec.packed_triplets = True
        if levels is not None:
            spec.levels_high, spec.levels_low = (int(levels[0] or 0), int(levels[1] or 0))
        for name, value in options.items():
            spec.options[name.replace("_", "-")] = _option_text(value)
        return spec

    def _run(self, spec, payload, progress, timeout, chunk_bytes, assembler=None):
        if self._replicas is not None:
            return self._run_on_replicas(spec, payload, progress, timeout, chunk_bytes)
        spec.input_bytes = len(payload)
        if "input_crc32" in spec.DESCRIPTOR.fields_by_name:
            # The whole input's CRC-32, checked by the server (a lost or reordered chunk).
            spec.input_crc32 = zlib.crc32(payload) & 0xFFFFFFFF
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

        call = self._run_raw(requests(), timeout=timeout)
        if assembler is None:
            assembler = _Assembler(progress)
        try:
            for event in call:
                assembler.add_bytes(event)
        except grpc.RpcError as e:
            raise Error(e.code(), e.details(), accepted=bool(assembler.job_id)) from None
        except BaseException:
            # A broken stream, or the progress callback raised (Ctrl-C too): the job is
            # cancelled on the server, not left running for nobody.
            call.cancel()
            raise
        if assembler.failed is not None:
            raise Error(assembler.failed.code, assembler.failed.message,
                        accepted=bool(assembler.job_id))
        if spec.detach:
            if not assembler.job_id:
                raise Error(grpc.StatusCode.DATA_LOSS, "the server did not detach the job")
            return assembler.job_id
        return assembler.finish()
