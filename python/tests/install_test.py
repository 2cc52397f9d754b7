"""`pip install` of python/ into a fresh venv, then the installed package alone: its version,
its bundled server (Client() with no address), a tiny job and an estimator.

Run by ctest as PythonInstall (tests/CMakeLists.txt):
    MLCLUST_SOURCE_DIR=. MLCLUST_BUILD_DIR=build /usr/bin/python3 -m unittest \\
        python/tests/install_test.py
The venv is Debian's `python3 -m venv --system-site-packages` (numpy, grpcio, protobuf and
scikit-learn are Debian's); pip gets --no-build-isolation --no-index, so nothing is fetched.
python/ is copied into the temporary folder first, so nothing is written into the checkout.
"""

import os
import shutil
import subprocess
import sys
import tempfile
import textwrap
import unittest

SOURCE = os.path.abspath(os.environ.get("MLCLUST_SOURCE_DIR", "."))
BUILD = os.path.abspath(os.environ.get("MLCLUST_BUILD_DIR", os.path.join(SOURCE, "build")))


class InstallTest(unittest.TestCase):
    def test_pip_install_into_a_fresh_venv_runs_a_job(self):
        with tempfile.TemporaryDirectory() as scratch:
            venv = os.path.join(scratch, "venv")
            subprocess.run(["/usr/bin/python3", "-m", "venv", "--system-site-packages", venv],
                           check=True, timeout=120)
            python = os.path.join(venv, "bin", "python")
            copy = os.path.join(scratch, "python")
            shutil.copytree(os.path.join(SOURCE, "python"), copy,
                            ignore=shutil.ignore_patterns("__pycache__", "build", "*.egg-info"))
            # Only what the package itself brings: no PYTHONPATH, no MLCLUST_BIN.
            env = {k: v for k, v in os.environ.items()
                   if k not in ("PYTHONPATH", "MLCLUST_BIN", "MLCLUST_DRACO_LIB")}
            env.update(MLCLUST_SOURCE_DIR=SOURCE, MLCLUST_BUILD_DIR=BUILD,
                       MLCLUST_BUILD_JOBS="2", PIP_NO_INPUT="1")
            installed = subprocess.run(
                [python, "-m", "pip", "install", "--no-build-isolation", "--no-index", copy],
                capture_output=True, text=True, timeout=600, env=env, cwd=scratch)
            self.assertEqual(installed.returncode, 0, installed.stdout + installed.stderr)
            script = textwrap.dedent("""
                import os, stat, sys
                import numpy as np
                import mlclust
                package = os.path.dirname(mlclust.__file__)
                assert package.startswith(sys.prefix), (package, sys.prefix)
                binary = os.path.join(package, "bin", "mlclust")
                assert not os.path.islink(binary) and os.access(binary, os.X_OK), binary
                with mlclust.Client() as client:
                    assert client.address.startswith("unix:"), client.address
                    print(mlclust.__version__ == client.info().version, mlclust.__version__)
                    points = np.array([[0, 0], [0, 1], [10, 0], [10, 1]], dtype=np.float32)
                    h = client.cluster_points(points, algo="kmeans", clusters=2)
                    print(h.labels(2).tolist())
                model = mlclust.KMeans(n_clusters=2).fit(points)
                print(model.labels_.tolist(), model.cluster_centers_.tolist())
            """)
            ran = subprocess.run([python, "-c", script], capture_output=True, text=True,
                                 timeout=120, env=env, cwd=scratch)
            self.assertEqual(ran.returncode, 0, ran.stderr)
            with open(os.path.join(SOURCE, "CMakeLists.txt")) as f:
                version = f.read().split("project(mlclust VERSION ", 1)[1].split()[0]
            self.assertEqual(ran.stdout.splitlines(), [
                f"True {version}", "[0, 0, 1, 1]",
                "[0, 0, 1, 1] [[0.0, 0.5], [10.0, 0.5]]"])


if __name__ == "__main__":
    unittest.main()
