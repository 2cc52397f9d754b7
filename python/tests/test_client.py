"""Tests of the mlclust Python package against a real server (`mlclust serve`).

Run by ctest (tests/CMakeLists.txt) as
    MLCLUST_BIN=build/client/mlclust MLCLUST_DATA=data PYTHONPATH=build/python \
        /usr/bin/python3 -m unittest discover -s python/tests -v
"""

import os
import subprocess
import time
import unittest

import grpc
import numpy as np

import mlclust
from served import BIN, DATA, ServedTestCase



def read_off(path):
    """A plain OFF file's vertices and triangles (the fixtures are triangle meshes)."""
    with open(path) as f:
        words = [w for line in f for w in line.split("#")[0].split()]
    assert words[0] == "OFF", path
    nv, nf = int(words[1]), int(words[2])
    at = 4
    vertices = np.array(words[at:at + 3 * nv], dtype=np.float32).reshape(nv, 3)
    at += 3 * nv
    faces = []
    for _ in range(nf):
        n = int(words[at])
        assert n == 3, "a triangle mesh is expected"
        faces.append([int(w) for w in words[at + 1:at + 4]])
        at += 1 + n
    return vertices, np.array(faces, dtype=np.int64)


def grid(n):
    """An n x n grid of squares in the plane z = 0, two triangles each."""
    xs, ys = np.meshgrid(np.arange(n + 1), np.arange(n + 1))
    vertices = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], axis=1)
    faces = []
    for j in range(n):
        for i in range(n):
            a, b = j * (n + 1) + i, j * (n + 1) + i + 1
            c, d = a + n + 1, b + n + 1
            faces += [[a, b, c], [c, b, d]]
    return vertices.astype(np.float32), np.array(faces)


def face_components(faces, labels):
    """The number of connected pieces (across shared edges) of each cluster, summed."""
    parent = list(range(len(faces)))

    def find(x):
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    edge_face = {}
    for f, (a, b, c) in enumerate(faces):
        for u, v in ((a, b), (b, c), (c, a)):
            key = (min(u, v), max(u, v))
            g = edge_face.setdefault(key, f)
            if g != f and labels[g] == labels[f]:
                parent[find(f)] = find(g)
    return len({find(f) for f in range(len(faces))})


def read_levels_csv(path):
    with open(path) as f:
        rows = f.read().split()[1:]
    return [(int(r.split(",")[0]), float(r.split(",")[1])) for r in rows]


class ServerTest(ServedTestCase):
    @classmethod
    def connect(cls):
        cls.client = mlclust.Client(cls.address)  # gRPC's default limits
        cls.fandisk = read_off(os.path.join(DATA, "fandisk.off"))

    @classmethod
    def disconnect(cls):
        if hasattr(cls, "client"):
            cls.client.close()

    def cli(self, *args):
        result = subprocess.run([BIN, *args, "--server", self.address, "--quiet"],
                                capture_output=True, text=True, timeout=300)
        self.assertEqual(result.returncode, 0, result.stderr)
        return result

    def path(self, name):
        return os.path.join(self.dir.name, name)

    # --- meshes ------------------------------------------------------------------------
    def test_a_detached_job_watched_from_any_level_equals_an_attached_run(self):
        vertices, faces = grid(20)  # 800 faces
        attached = self.client.cluster_mesh(vertices, faces, algo="hc")
        job = self.client.cluster_mesh(vertices, faces, algo="hc", detach=True)
        self.assertRegex(job, r"^job-[0-9a-f]{32}$")
        whole = self.client.watch(job)
        part = self.client.watch(job, from_level=700)
        self.assertEqual(whole.job_id, job)
        self.assertEqual([(l.cluster_count, l.energy) for l in whole.levels],
                         [(l.cluster_count, l.energy) for l in attached.levels])
        self.assertEqual([(l.cluster_count, l.energy) for l in part.levels],
                         [(l.cluster_count, l.energy) for l in attached.levels][700:])
        for k in (400, 50, 3):
            np.testing.assert_array_equal(whole.labels(k), attached.labels(k))
        for k in (100, 50, 3):  # level 700 of 800 faces: 100 clusters
            np.testing.assert_array_equal(part.labels(k), attached.labels(k))
        summary = {j.job_id: j for j in self.client.jobs()}[job]
        self.assertEqual(summary.state, "succeeded")
        self.assertTrue(summary.detached)
        self.assertEqual(summary.levels, len(attached.levels))
        self.assertEqual(self.client.cancel(job), "succeeded")  # ended: left as it is
        with self.assertRaises(mlclust.Error) as missing:
            self.client.watch("job-999999")
        self.assertEqual(missing.exception.code, grpc.StatusCode.NOT_FOUND)
        # The CLI watches the same job from another process: the same labels.
        self.cli("watch", job, "--clusters", "50", "--labels", self.path("watched.txt"))
        with open(self.path("watched.txt")) as f:
            cli_labels = np.array(f.read().split(), dtype=np.int64)
        np.testing.assert_array_equal(cli_labels, attached.labels(50))

    def test_fandisk_ml_levels_and_labels_equal_the_clis(self):
        vertices, faces = self.fandisk
        h = self.client.cluster_mesh(vertices, faces, algo="ml", energy="cvd")
        self.cli("mesh", os.path.join(DATA, "fandisk.off"), "--algo", "ml", "--clusters", "50",
                 "--levels-csv", self.path("ml.csv"), "--labels", self.path("ml.txt"),
                 "--ply", self.path("ml.ply"))
        want = read_levels_csv(self.path("ml.csv"))
        self.assertEqual(len(h.levels), len(want))
        self.assertEqual([(l.cluster_count, l.energy) for l in h.levels], want)
        self.assertEqual(h.num_elements, len(faces))
        cli_labels = np.loadtxt(self.path("ml.txt"), dtype=np.int64)
        np.testing.assert_array_equal(h.labels(50), cli_labels)
        self.assertEqual(len(np.unique(h.labels(50))), 50)
        self.assertEqual(h.energy(50), dict(want)[50])
        self.assertEqual(h.done.final_clusters, h.levels[-1].cluster_count)
        # The same file as the CLI's --ply, byte for byte.
        mlclust.write_clustered(self.path("python.ply"), vertices, faces, h.labels(50))
        with open(self.path("python.ply"), "rb") as a, open(self.path("ml.ply"), "rb") as b:
            self.assertEqual(a.read(), b.read())

    def test_stepping_forward_and_back_gives_the_same_labels(self):
        vertices, faces = self.fandisk
        h = self.client.cluster_mesh(vertices, faces, algo="hc")
        last = len(h) - 1
        snapshot = h.labels(level=0, compact=False)
        self.assertEqual(len(np.unique(snapshot)), h.levels[0].cluster_count)
        middle = h.labels(level=last // 2, compact=False)
        end = h.labels(level=last, compact=False)
        # Back to the start by applying every level's `from`.
        np.testing.assert_array_equal(h.labels(level=0, compact=False), snapshot)
        # Level by level forward, then back, through every level: each has its count.
        for level, labels in h:
            if level.index % 997 == 0 or level.index == last:
                self.assertEqual(len(np.unique(labels)), level.cluster_count)
        self.assertEqual(h.position, last)
        np.testing.assert_array_equal(h.current_labels(), end)
        while h.position > last // 2:
            h.step(-1)
        np.testing.assert_array_equal(h.current_labels(), middle)
        self.assertEqual(h.seek(0), 0)
        np.testing.assert_array_equal(h.current_labels(), snapshot)
        # A level's triplets move each element once, from its label before the level.
        h.seek(9)
        element, to, frm = h.triplets(10)
        self.assertEqual(len(np.unique(element)), len(element))
        np.testing.assert_array_equal(h.current_labels()[element], frm)
        h.step()
        np.testing.assert_array_equal(h.current_labels()[element], to)
        with self.assertRaises(IndexError):
            h.seek(len(h))

    def test_single_level_algorithm_and_options(self):
        vertices, faces = self.fandisk
        h = self.client.cluster_mesh(vertices, faces, algo="emlo", clusters=30, guard=True,
                                     init="lneigh")
        self.assertEqual(h.levels[-1].cluster_count, 30)
        labels = h.labels(30)
        self.assertEqual(len(np.unique(labels)), 30)
        self.assertLessEqual(h.energy(30), h.levels[0].energy)

    def test_edgebreaker_upload_keeps_labels_on_the_clients_faces(self):
        vertices, faces = self.fandisk
        h = self.client.cluster_mesh(vertices, faces, algo="ml",
                                     draco={"method": "edgebreaker", "quantization_bits": 14})
        labels = h.labels(40)
        # ML clusters are connected: on the client's own faces each label is one piece.
        # Labels that followed edgebreaker's order instead would be scattered.
        self.assertEqual(face_components(faces, labels), 40)
        # Without face ids the same labels are scattered over the client's faces.
        scrambled = self.client.cluster_mesh(vertices, faces, algo="ml", draco={
            "method": "edgebreaker", "quantization_bits": 14, "face_ids": False})
        self.assertGreater(face_components(faces, scrambled.labels(40)), 400)

    def test_progress_is_reported(self):
        vertices, faces = self.fandisk
        seen = []
        self.client.cluster_mesh(vertices, faces, algo="hc", progress=seen.append)
        stages = [p.stage for p in seen]
        self.assertEqual(stages[0], "queued")
        self.assertIn("decode", stages)
        self.assertIn("levels", stages)
        received = [p.levels_received for p in seen]
        self.assertEqual(received, sorted(received))
        self.assertGreater(received[-1], 1)

    def test_a_raising_progress_callback_cancels_the_job(self):
        vertices, faces = grid(300)
        before = self.client.stats().jobs_cancelled

        def stop(progress):
            if progress.levels_received > 0:
                raise KeyboardInterrupt

        with self.assertRaises(KeyboardInterrupt):
            self.client.cluster_mesh(vertices, faces, algo="ml", progress=stop)
        deadline = time.time() + 30
        while self.client.stats().jobs_cancelled == before and time.time() < deadline:
            time.sleep(0.05)
        self.assertEqual(self.client.stats().jobs_cancelled, before + 1)

    def test_default_limits_client_receives_more_than_4_mib(self):
        vertices, faces = grid(160)  # 51,200 faces
        h = self.client.cluster_mesh(vertices, faces, algo="hc")
        self.assertGreater(h.num_triplets * 12, 4 << 20)  # the levels need several messages
        self.assertEqual(h.levels[-1].cluster_count, 1)
        self.assertEqual(len(np.unique(h.labels(7))), 7)

    # --- mesh files --------------------------------------------------------------------
    def test_read_mesh_and_write_clustered(self):
        vertices, faces = mlclust.read_mesh(os.path.join(DATA, "fandisk.off"))
        np.testing.assert_array_equal(vertices, self.fandisk[0])
        np.testing.assert_array_equal(faces, self.fandisk[1])
        self.assertEqual(faces.dtype, np.uint32)
        labels = np.arange(len(faces)) % 7 - 1  # -1: unlabelled
        for name in ("out.ply", "out.glb", "out.gltf"):
            mlclust.write_clustered(self.path(name), vertices, faces, labels)
            v, f = mlclust.read_mesh(self.path(name))
            self.assertEqual(len(f), len(faces))
            np.testing.assert_array_equal(v[f], vertices[faces])  # each face's corners
        with self.assertRaises(mlclust.Error) as e:
            mlclust.read_mesh(self.path("missing.obj"))
        self.assertEqual(e.exception.code, grpc.StatusCode.NOT_FOUND)
        with self.assertRaises(mlclust.Error) as e:
            mlclust.write_clustered(self.path("x.stl"), vertices, faces, labels)
        self.assertEqual(e.exception.code, grpc.StatusCode.INVALID_ARGUMENT)
        with self.assertRaises(ValueError):
            mlclust.write_clustered(self.path("x.ply"), vertices, faces, labels[:-1])

    def test_default_limits_client_on_a_million_faces(self):
        vertices, faces = grid(710)  # 1,008,200 faces
        h = self.client.cluster_mesh(vertices, faces, algo="emlo", clusters=1000)
        self.assertEqual(h.num_elements, len(faces))
        self.assertEqual([l.cluster_count for l in h.levels], [1000, 1000])
        self.assertEqual(len(np.unique(h.labels(1000))), 1000)
        self.assertLess(h.levels[-1].energy, h.levels[0].energy)

    # --- points ------------------------------------------------------------------------
    def test_points_levels_equal_the_clis(self):
        rng = np.random.default_rng(5)
        centres = np.array([[0, 0, 0], [10, 0, 0], [0, 10, 0], [0, 0, 10]], dtype=np.float32)
        x = np.concatenate([c + rng.normal(size=(300, 3)).astype(np.float32) for c in centres])
        h = self.client.cluster_points(x, algo="ml")
        np.save(self.path("blobs.npy"), x)
        self.cli("points", self.path("blobs.npy"), "--algo", "ml",
                 "--levels-csv", self.path("points.csv"))
        self.assertEqual([(l.cluster_count, l.energy) for l in h.levels],
                         read_levels_csv(self.path("points.csv")))
        labels = h.labels(4)
        for block in range(4):  # each blob is one cluster
            self.assertEqual(len(np.unique(labels[300 * block:300 * (block + 1)])), 1)
        km = self.client.cluster_points(x, algo="kmeans", clusters=4)
        self.assertEqual(len(np.unique(km.labels(4))), 4)

    def test_xmeans_finds_k_and_bisecting_gives_levels_down_to_one(self):
        rng = np.random.default_rng(5)
        centres = np.array([[0, 0, 0], [10, 0, 0], [0, 10, 0], [0, 0, 10]], dtype=np.float32)
        x = np.concatenate([c + rng.normal(size=(300, 3)).astype(np.float32) for c in centres])
        xm = self.client.cluster_points(x, algo="xmeans", clusters=1, kmax=16)
        self.assertEqual([l.cluster_count for l in xm.levels], [1, 4])  # k_min, then found
        labels = xm.labels(4)
        for block in range(4):
            self.assertEqual(len(np.unique(labels[300 * block:300 * (block + 1)])), 1)
        bk = self.client.cluster_points(x, algo="bisecting", clusters=6, split="energy")
        self.assertEqual([l.cluster_count for l in bk.levels], [6, 5, 4, 3, 2, 1])
        energies = [l.energy for l in bk.levels]
        self.assertEqual(energies, sorted(energies))  # undoing splits never lowers it

    # --- errors ------------------------------------------------------------------------
    def test_errors_raise_with_the_status_code_and_message(self):
        vertices, faces = self.fandisk
        with self.assertRaises(mlclust.Error) as e:
            self.client.cluster_mesh(vertices, faces, algo="emlo", clusters=len(faces) + 1)
        self.assertEqual(e.exception.code, grpc.StatusCode.INVALID_ARGUMENT)
        self.assertIn("more than the mesh's", e.exception.details)
        with self.assertRaises(mlclust.Error) as e:
            self.client.cluster_mesh(vertices, faces, algo="ml", energy="cvd-adaptive",
                                     gamma="steep")
        self.assertEqual(e.exception.code, grpc.StatusCode.INVALID_ARGUMENT)
        self.assertIn("gamma", e.exception.details)
        with self.assertRaises(mlclust.Error) as e:  # refused by the encoder, locally
            self.client.cluster_mesh(vertices, np.array([[0, 1, len(vertices)]]))
        self.assertEqual(e.exception.code, grpc.StatusCode.INVALID_ARGUMENT)
        self.assertIn("out of range", e.exception.details)
        with self.assertRaises(ValueError):
            self.client.cluster_mesh(vertices, faces, algo="nope")
        with self.assertRaises(mlclust.Error) as e:
            mlclust.Client("127.0.0.1:1").cluster_points(np.zeros((3, 2)), timeout=5)
        self.assertEqual(e.exception.code, grpc.StatusCode.UNAVAILABLE)


if __name__ == "__main__":
    unittest.main()
