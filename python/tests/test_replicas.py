"""The Python client over several servers (replicas): three `mlclust serve` on loopback,
one killed; jobs are skipped past a gone replica (never one that accepted them), results
equal a solo run's, a detached job's id names its replica and a gone replica is reported.

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
