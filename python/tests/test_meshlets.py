"""read_meshlets on the file `mlclust mesh INPUT --meshlets FILE` writes (issue 29): the
caps, every face once, each meshlet's triangles the input's faces, and the bounds.

Run with the package's other tests (tests/CMakeLists.txt, PythonClient).
"""

import os
import subprocess
import tempfile
import unittest

import numpy as np

import mlclust
import served


class ReadMeshlets(unittest.TestCase):
    def test_file_of_the_cli(self):
        path = os.path.join(served.DATA, "elephant-with-holes.off")
        vertices, faces = mlclust.read_mesh(path)
        with tempfile.TemporaryDirectory() as work:
            out = os.path.join(work, "m.meshlets")
            subprocess.run([served.BIN, "mesh", path, "--meshlets", out, "--max-vertices", "48",
                            "--max-triangles", "64"], check=True, stdout=subprocess.DEVNULL)
            m = mlclust.read_meshlets(out)
        self.assertEqual((m.max_vertices, m.max_triangles), (48, 64))
        self.assertEqual(m.vertex_count, len(vertices))
        self.assertTrue((m.meshlets[:, 2] <= 48).all() and (m.meshlets[:, 3] <= 64).all())
        self.assertEqual(sorted(m.triangle_faces.tolist()), list(range(len(faces))))
        first = 0
        for k in range(len(m.meshlets)):
            count = int(m.meshlets[k, 3])
            own = m.triangle_faces[first:first + count]
            np.testing.assert_array_equal(m.triangles(k), faces[own])
            self.assertTrue((m.face_meshlet[own] == k).all())
            first += count
        self.assertEqual(len(m.bounds), len(m.meshlets))
        # Each sphere holds its meshlet's vertices.
        for k in range(len(m.meshlets)):
            corners = vertices[m.triangles(k).ravel()]
            distance = np.linalg.norm(corners - m.bounds["center"][k], axis=1)
            self.assertLessEqual(distance.max(), m.bounds["radius"][k] * (1 + 1e-4) + 1e-5)

    def test_refuses_a_damaged_file(self):
        with tempfile.TemporaryDirectory() as work:
            bad = os.path.join(work, "bad.meshlets")
            with open(bad, "wb") as f:
                f.write(b"MLCMSHLT" + bytes(60))
            with self.assertRaisesRegex(ValueError, "version 0"):
                mlclust.read_meshlets(bad)


if __name__ == "__main__":
    unittest.main()
