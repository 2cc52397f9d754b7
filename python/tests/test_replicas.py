"""The Python client over several servers (replicas): three `mlclust serve` on loopback,
one killed; jobs are skipped past a gone replica, results equal a solo run's, a detached
job's id names its replica and a gone replica is reported. A replica lost after accepting
a job (its connection cut in the middle of the levels) loses no job: it is submitted again,
the levels received kept and reported once; a detached job lost with its replica is
submitted again by watch(..., resubmit=...).

    MLCLUST_BIN=build/client/mlclust PYTHONPATH=build/python \\
        /usr/bin/python3 -m unittest discover -s python/tests -p 'test_replicas.py'
"""

import re
import socket
import tempfile
import unittest

import grpc
import numpy as np

import mlclust
from served import start_server, stop_server
from test_watch_resume import CuttingProxy


def grid(n):
    """An n x n grid of squares, two triangles each, slightly wavy."""
    i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1))
    vertices = np.stack([i.ravel(), j.ravel(),
                         0.3 * np.sin(i.ravel() * 0.7) * np.cos(j.ravel() * 0.4)], 1)
    a = (np.arange(n)[None, :] + (n + 1) * np.arange(n)[:, None]).ravel()
    faces = np.concatenate([np.stack([a, a + 1, a + n + 2], 1),
                            np.stack([a, a + n + 2, a + n + 1], 1)])
    return vertices.astype(np.float32), faces.astype(np.uint32)


def free_port_address():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return f"127.0.0.1:{s.getsockname()[1]}"


class ReplicasTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = tempfile.TemporaryDirectory()
        cls.servers = [start_server(cls.dir.name, name, "--gpu", "off") for name in "abc"]
        cls.addresses = [address for _, _, address in cls.servers]

    @classmethod
    def tearDownClass(cls):
        for process, log, _ in cls.servers:
            stop_server(process, log)
        cls.dir.cleanup()

    def test_addresses(self):
        self.assertIsNone(mlclust.client.resolve_replicas("127.0.0.1:1"))
        self.assertEqual(mlclust.client.resolve_replicas("127.0.0.1:1, [::1]:2,127.0.0.1:1"),
                         ["127.0.0.1:1", "[::1]:2"])
        self.assertTrue(all(a.endswith(":5")
                            for a in mlclust.client.resolve_replicas("dns:///localhost:5")))
        with self.assertRaises(ValueError):
            mlclust.client.resolve_replicas("127.0.0.1:1,,127.0.0.1:2")
        self.assertEqual(mlclust.client.split_job_id("[::1]:7/job-000003"),
                         ("[::1]:7", "job-000003"))
        self.assertEqual(mlclust.client.split_job_id("job-000003"), (None, "job-000003"))

    def test_jobs_skip_a_gone_replica_and_equal_a_solo_run(self):
        vertices, faces = grid(20)
        with mlclust.Client(self.addresses[0]) as solo_client:
            solo = solo_client.cluster_mesh(vertices, faces, algo="ml")
        dead = free_port_address()
        with mlclust.Client([dead] + self.addresses, spread="in-order") as client:
            result = client.cluster_mesh(vertices, faces, algo="ml")
            self.assertTrue(result.job_id.startswith(self.addresses[0] + "/"), result.job_id)
            np.testing.assert_array_equal(result.labels(10), solo.labels(10))
            self.assertEqual([l.energy for l in result.levels], [l.energy for l in solo.levels])
        with mlclust.Client(",".join([dead] + self.addresses)) as client:
            for _ in range(4):
                result = client.cluster_mesh(vertices, faces, algo="ml")
                self.assertFalse(result.job_id.startswith(dead), result.job_id)
                np.testing.assert_array_equal(result.labels(10), solo.labels(10))
            self.assertIsInstance(client.stats()[dead], mlclust.Error)
        with mlclust.Client([dead, free_port_address()]) as client:
            with self.assertRaises(mlclust.Error) as caught:
                client.cluster_mesh(vertices, faces)
            self.assertEqual(caught.exception.code, grpc.StatusCode.UNAVAILABLE)
            self.assertIn("no replica accepted the job", caught.exception.details)

    def assert_same_levels(self, a, b):
        self.assertEqual([(l.cluster_count, l.energy) for l in a.levels],
                         [(l.cluster_count, l.energy) for l in b.levels])
        for k in (40000, 5000, 100, 7, 1):
            np.testing.assert_array_equal(a.labels(k), b.labels(k))

    def lost_replica(self):
        """A proxy to replica A cut 600,000 bytes into its first connection (of HC's ~4 MB
        stream on a 150 x 150 grid, in batches of 5,000 triplets: after some batches);
        later connections get nothing back."""
        port = int(self.addresses[0].rsplit(":", 1)[1])
        return CuttingProxy(port, [600_000] + [0] * 8)

    def test_a_job_whose_replica_is_lost_mid_job_is_submitted_again(self):
        vertices, faces = grid(150)  # 45,000 faces
        with mlclust.Client(self.addresses[1]) as solo_client:
            solo = solo_client.cluster_mesh(vertices, faces, algo="hc")
        proxy = self.lost_replica()
        lost = f"127.0.0.1:{proxy.port}"
        resubmits, reported = [], []

        def progress(p):
            if p.stage == "levels":
                reported.append(p.levels_received)

        try:
            with mlclust.Client([lost, self.addresses[1]], spread="in-order",
                                on_resubmit=lambda *a: resubmits.append(a)) as client:
                result = client.cluster_mesh(vertices, faces, algo="hc", progress=progress,
                                             batch_triplets=5000)
        finally:
            proxy.close()
        self.assertEqual(len(resubmits), 1)
        replica, error, attempt, limit, kept = resubmits[0]
        self.assertEqual((replica, attempt, limit), (lost, 1, 2))
        self.assertIn(error.code, (grpc.StatusCode.UNAVAILABLE, grpc.StatusCode.INTERNAL,
                                   grpc.StatusCode.UNKNOWN))
        self.assertGreater(kept, 1)
        self.assertLess(kept, len(solo.levels))
        self.assertTrue(result.job_id.startswith(self.addresses[1] + "/"), result.job_id)
        self.assert_same_levels(result, solo)
        # The levels the lost replica had sent are not reported again.
        self.assertEqual(reported, sorted(reported))
        self.assertEqual(reported[-1], len(solo.levels))

    def test_other_levels_from_a_replica_fail_the_job(self):
        u = lambda *v: np.array(v, dtype=np.uint32)
        # Four elements; level 1 merges 1 into 0, level 2 merges 3 into 2.
        kept = (u(0, 1, 2, 3), u(4, 3, 2), np.array([0.0, 1.0, 2.0]), u(0, 1, 2),
                u(1, 3), u(0, 2), u(1, 3))
        self.assertIs(mlclust.client._same_levels(kept, kept[:1] + (u(4, 3), kept[2][:2],
                                                                    u(0, 1), u(1), u(0), u(1))),
                      kept)
        self.assertIs(mlclust.client._same_levels(None, kept), kept)
        other = kept[:4] + (u(1, 2), u(0, 3), u(1, 2))  # level 2 merges another element
        with self.assertRaises(mlclust.Error) as caught:
            mlclust.client._same_levels(kept, other)
        self.assertEqual(caught.exception.code, grpc.StatusCode.DATA_LOSS)
        self.assertIn("level 2 differs from the one received before (its triplets differ)",
                      caught.exception.details)
        energy = kept[:2] + (np.array([0.0, 1.5, 2.0]),) + kept[3:]
        with self.assertRaises(mlclust.Error) as caught:
            mlclust.client._same_levels(kept, energy)
        self.assertIn("level 1 differs", caught.exception.details)

    def test_resubmissions_are_bounded(self):
        vertices, faces = grid(150)
        proxy = self.lost_replica()
        try:
            with mlclust.Client([f"127.0.0.1:{proxy.port}", self.addresses[1]],
                                spread="in-order", resubmit=0) as client:
                with self.assertRaises(mlclust.Error) as caught:
                    client.cluster_mesh(vertices, faces, algo="hc", batch_triplets=5000)
        finally:
            proxy.close()
        self.assertIn("the limit (resubmit=0)", caught.exception.details)
        self.assertTrue(caught.exception.accepted)

    def test_a_detached_job_lost_with_its_replica_is_submitted_again_by_watch(self):
        vertices, faces = grid(150)
        with mlclust.Client(self.addresses[1]) as solo_client:
            solo = solo_client.cluster_mesh(vertices, faces, algo="hc")
        with mlclust.Client(self.addresses[0]) as direct:
            job = direct.cluster_mesh(vertices, faces, algo="hc", detach=True,
                                      batch_triplets=5000)
        proxy = self.lost_replica()
        lost = f"127.0.0.1:{proxy.port}"
        resubmits = []
        try:
            with mlclust.Client([lost, self.addresses[1]],
                                on_resubmit=lambda *a: resubmits.append(a)) as client, \
                    mlclust.Client([self.addresses[1]]) as elsewhere:
                # The caller kept what rebuilds the job: submitting it again is one call.
                watched = client.watch(
                    f"{lost}/{job}", max_resumes=1, resume_delay=0.05,
                    resubmit=lambda: elsewhere.cluster_mesh(vertices, faces, algo="hc",
                                                            detach=True))
        finally:
            proxy.close()
        self.assertEqual(len(resubmits), 1)
        self.assertGreater(resubmits[0][4], 1)
        self.assertTrue(watched.job_id.startswith(self.addresses[1] + "/"), watched.job_id)
        self.assert_same_levels(watched, solo)

    def test_z_detached_job_names_its_replica_and_a_gone_replica_is_reported(self):
        vertices, faces = grid(20)
        b = self.addresses[1]
        with mlclust.Client([b] + self.addresses, spread="in-order") as client:
            job = client.cluster_mesh(vertices, faces, algo="ml", detach=True)
            self.assertRegex(job, "^" + re.escape(b) + r"/job-[0-9a-f]{32}$")
            self.assertEqual(client.watch(job).job_id, job)
            self.assertIn(job, [j.job_id for j in client.jobs()])
            process = self.servers[1][0]
            process.kill()
            process.wait(timeout=30)
            with self.assertRaises(mlclust.Error) as caught:
                client.watch(job, timeout=20)
            self.assertEqual(caught.exception.code, grpc.StatusCode.UNAVAILABLE)
            self.assertIn(f"replica {b}, which holds job", caught.exception.details)
            # The others still answer; jobs() lists theirs.
            self.assertTrue(all(not j.job_id.startswith(b) for j in client.jobs()))
            with self.assertRaises(ValueError):
                client.watch("job-000001")


if __name__ == "__main__":
    unittest.main()
