"""Per-polygon clustering through a real server (issue 13): cluster_mesh(...,
polygons=...) sends JobSpec.polygon_triangle_counts; ML, HC, PML, EMLO and BB then never
split a polygon and keep every cluster connected; bad counts are refused by index.

Run with the package's other tests (tests/CMakeLists.txt, PythonClient).
"""

import math
import os
import unittest

import grpc
import numpy as np

import mlclust
import served
import test_client

DATA = test_client.DATA


def wavy_quads(n):
    """n x n quads with a wavy height, each split as the readers split a polygon (a fan from
    its first corner): two triangles per quad, in quad order."""
    vertices = np.array([[i, j, 0.15 * math.sin(0.7 * i) + 0.1 * math.cos(0.9 * j)]
                         for j in range(n + 1) for i in range(n + 1)], dtype=np.float32)
    faces = []
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i
            b, c, d = a + 1, a + n + 2, a + n + 1
            faces += [[a, b, c], [a, c, d]]
    return vertices, np.array(faces), [2] * (n * n)


def off_polygon_counts(path):
    """The triangles of each face of an OFF file (n - 2 for n corners)."""
    with open(path) as f:
        words = [w for line in f for w in line.split("#")[0].split()]
    nv, nf = int(words[1]), int(words[2])
    at = 4 + 3 * nv
    counts = []
    for _ in range(nf):
        n = int(words[at])
        counts.append(n - 2)
        at += 1 + n
    return counts


class PolygonTest(served.ServedTestCase):
    @classmethod
    def connect(cls):
        cls.client = mlclust.Client(cls.address)

    @classmethod
    def disconnect(cls):
        if hasattr(cls, "client"):
            cls.client.close()

    def check(self, faces, counts, labels, k, what):
        first = np.concatenate(([0], np.cumsum(counts)[:-1]))
        per_polygon = mlclust.labels_per_polygon(labels, counts)
        self.assertTrue(np.array_equal(np.repeat(per_polygon, counts), labels),
                        f"{what}: a polygon is split")
        self.assertEqual(len(per_polygon), len(counts))
        self.assertTrue(np.array_equal(per_polygon, np.asarray(labels)[first]))
        self.assertEqual(len(np.unique(labels)), k, what)
        self.assertEqual(test_client.face_components(faces, labels), k,
                         f"{what}: a cluster is in several pieces")

    def test_quad_grid_no_level_splits_a_quad(self):
        vertices, faces, counts = wavy_quads(12)
        # On the triangles ML splits quads; with the polygons no level does.
        plain = self.client.cluster_mesh(vertices, faces, algo="ml", clusters=10)
        split = plain.labels(10).reshape(-1, 2)
        self.assertTrue(np.any(split[:, 0] != split[:, 1]), "the test shows nothing")
        for algo in ("ml", "hc", "pml"):
            h = self.client.cluster_mesh(vertices, faces, algo=algo, polygons=counts)
            self.assertEqual(h.levels[0].cluster_count, 144, algo)
            for level in h.levels:
                self.check(faces, counts, h.labels(level=level.index), level.cluster_count,
                           f"{algo} at {level.cluster_count} clusters")
        for algo in ("emlo", "bb"):
            h = self.client.cluster_mesh(vertices, faces, algo=algo, clusters=10,
                                         polygons=counts)
            self.check(faces, counts, h.labels(10), 10, algo)
            self.assertLessEqual(h.energy(10), h.levels[0].energy * (1 + 1e-12))

    def test_cgal_double_torus(self):
        path = os.path.join(DATA, "..", "tests", "fixtures", "cgal_double_torus_example.off")
        vertices, faces = mlclust.read_mesh(path)
        counts = off_polygon_counts(path)
        self.assertEqual(sum(counts), len(faces))
        for algo, k in (("ml", 12), ("emlo", 12), ("bb", 12)):
            h = self.client.cluster_mesh(vertices, faces, algo=algo, clusters=k, polygons=counts)
            self.check(faces, counts, h.labels(k), k, algo)

    def test_bad_counts_are_refused_naming_the_polygon(self):
        vertices, faces, counts = wavy_quads(4)
        cases = [
            ([2, 2, 0] + [2] * 13, "polygon 2 has 0 triangles"),
            ([2] * 15, "add up to 30, not the mesh's 32 faces"),
            ([1, 2] + [2] * 14 + [1], "polygon 1 (faces 1..2) is not edge-connected"),
        ]
        for bad, message in cases:
            with self.assertRaises(mlclust.Error) as e:
                self.client.cluster_mesh(vertices, faces, algo="ml", polygons=bad)
            self.assertEqual(e.exception.code, grpc.StatusCode.INVALID_ARGUMENT, bad)
            self.assertIn(message, e.exception.details)
        with self.assertRaises(mlclust.Error) as e:
            self.client.cluster_mesh(vertices, faces, algo="vsa", energy="planar", clusters=3,
                                     polygons=counts)
        self.assertEqual(e.exception.code, grpc.StatusCode.INVALID_ARGUMENT)
        self.assertIn("not vsa", e.exception.details)
        with self.assertRaises(mlclust.Error) as e:
            self.client.cluster_mesh(vertices, faces, algo="emlo", clusters=17, polygons=counts)
        self.assertIn("16 polygons", e.exception.details)


if __name__ == "__main__":
    unittest.main()
