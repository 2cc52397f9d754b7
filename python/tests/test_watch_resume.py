"""Client.watch resumes a broken stream where it stopped (as the C++ client does): through
a proxy that cuts the connection after a number of bytes from the server, the watched
hierarchy equals one watched directly, and a stream that cannot be resumed raises.

Run with the other tests (see test_client.py for the environment)."""

import socket
import threading
import unittest

import grpc
import numpy as np

import mlclust

from served import ServedTestCase
from test_client import grid


class CuttingProxy:
    """A TCP proxy on 127.0.0.1 to `target`: connection i is cut (both sides closed) once
    cuts[i] bytes came from the server; connections past the list are passed through."""

    def __init__(self, target_port, cuts):
        self._target = ("127.0.0.1", target_port)
        self._cuts = list(cuts)
        self._listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self._listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self._listener.bind(("127.0.0.1", 0))
        self._listener.listen(16)
        self.port = self._listener.getsockname()[1]
        self.connections = 0
        self.cut = 0
        self._stop = False
        threading.Thread(target=self._accept, daemon=True).start()

    def close(self):
        self._stop = True
        self._listener.close()

    def _accept(self):
        while not self._stop:
            try:
                client, _ = self._listener.accept()
            except OSError:
                return
            limit = self._cuts[self.connections] if self.connections < len(self._cuts) else None
            self.connections += 1
            server = socket.create_connection(self._target)
            threading.Thread(target=self._pump, args=(client, server, None), daemon=True).start()
            threading.Thread(target=self._pump, args=(server, client, limit), daemon=True).start()

    def _pump(self, source, sink, limit):
        sent = 0
        try:
            while True:
                data = source.recv(65536)
                if not data:
                    break
                if limit is not None and sent + len(data) >= limit:
                    sink.sendall(data[:limit - sent])
                    self.cut += 1
                    break
                sink.sendall(data)
                sent += len(data)
        except OSError:
            pass
        for s in (source, sink):
            try:
                s.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            s.close()


class WatchResumeTest(ServedTestCase):
    @classmethod
    def connect(cls):
        cls.port = int(cls.address.rsplit(":", 1)[1])
        cls.client = mlclust.Client(cls.address)
        # 45,000 faces: HC's 45,000 levels (323,032 triplets) take several level batches.
        vertices, faces = grid(150)
        cls.job = cls.client.cluster_mesh(vertices, faces, algo="hc", detach=True)
        cls.direct = cls.client.watch(cls.job)

    @classmethod
    def disconnect(cls):
        if hasattr(cls, "client"):
            cls.client.close()

    def assert_same(self, a, b):
        self.assertEqual(len(a.levels), len(b.levels))
        self.assertEqual([(l.cluster_count, l.energy) for l in a.levels],
                         [(l.cluster_count, l.energy) for l in b.levels])
        for k in (40000, 5000, 100, 7, 1):
            np.testing.assert_array_equal(a.labels(k), b.labels(k))

    def test_a_watch_cut_twice_resumes_and_equals_a_direct_one(self):
        # Cut inside the first level batch, then (the resumed stream) deep in the third.
        proxy = CuttingProxy(self.port, [200_000, 1_500_000])
        resumed = []
        try:
            with mlclust.Client(f"127.0.0.1:{proxy.port}") as client:
                watched = client.watch(self.job, resume_delay=0.1, on_resume=resumed.append)
        finally:
            proxy.close()
        self.assertEqual(proxy.cut, 2)
        self.assertEqual(len(resumed), 2)
        self.assertTrue(all(isinstance(e, mlclust.Error) for e in resumed))
        self.assertEqual(watched.job_id, self.job)
        self.assert_same(watched, self.direct)

    def test_a_watch_from_a_level_resumes_too(self):
        proxy = CuttingProxy(self.port, [1_000_000])
        resumed = []
        try:
            with mlclust.Client(f"127.0.0.1:{proxy.port}") as client:
                watched = client.watch(self.job, from_level=30000, resume_delay=0.1,
                                       on_resume=resumed.append)
        finally:
            proxy.close()
        self.assertEqual(proxy.cut, 1)
        self.assertEqual(len(resumed), 1)
        self.assertEqual(len(watched.levels), len(self.direct.levels) - 30000)
        for k in (15000, 100, 1):
            np.testing.assert_array_equal(watched.labels(k), self.direct.labels(k))

    def test_without_resumes_a_broken_stream_raises(self):
        proxy = CuttingProxy(self.port, [200_000])
        try:
            with mlclust.Client(f"127.0.0.1:{proxy.port}") as client:
                with self.assertRaises(mlclust.Error) as broken:
                    client.watch(self.job, max_resumes=0)
        finally:
            proxy.close()
        self.assertEqual(broken.exception.code, grpc.StatusCode.UNAVAILABLE)


class AssemblerResumeTest(unittest.TestCase):
    """The resume bookkeeping without a server: a level split across batches and cut
    short is dropped, and the resumed stream's whole level takes its place."""

    def test_a_split_level_cut_short_is_dropped_and_sent_again_whole(self):
        from mlclust.client import _Assembler

        def u(*values):
            return np.array(values, dtype=np.uint32)

        energy = lambda e: np.array([e], dtype=np.float64)
        a = _Assembler(None, absolute_levels=True)
        self.assertEqual(a.last_complete_level(), -1)
        a._snapshot(10, 4, 0.0, u(0, 1, 2, 3), 0, 4)  # the job's level 10: 4 clusters
        a._levels(11, u(3), energy(1.0), u(1), u(3), u(2), u(3), u(11))  # 3 -> 2
        # Level 12's first piece (1 -> 0); its second never comes: the stream broke.
        a._levels(12, u(2), energy(2.0), u(1), u(1), u(0), u(1), u(12),
                  last_level_continues=True)
        self.assertEqual(a.last_complete_level(), 11)
        a.drop_partial_level()
        self.assertEqual(a.last_complete_level(), 11)
        # The resumed stream (from level 11, resume) sends level 12 whole, then 13.
        a._levels(12, u(2), energy(2.0), u(2), u(1, 2), u(0, 0), u(1, 2), u(12))
        a._levels(13, u(1), energy(3.0), u(1), u(3), u(0), u(3), u(13))
        a.done = mlclust.client.pb.Done()
        h = a.finish()
        self.assertEqual([l.cluster_count for l in h.levels], [4, 3, 2, 1])
        self.assertEqual(h.num_triplets, 4)
        np.testing.assert_array_equal(h.labels(level=2, compact=False), [0, 0, 0, 2])
        np.testing.assert_array_equal(h.labels(level=3, compact=False), [0, 0, 0, 0])


if __name__ == "__main__":
    unittest.main()
