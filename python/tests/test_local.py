"""Client() with no address: the bundled `mlclust serve` on a private Unix socket, started
and stopped with the client (close, `with`, garbage collection, interpreter exit)."""

import gc
import os
import stat
import subprocess
import sys
import textwrap
import unittest

import numpy as np

import mlclust
from served import BIN, ServedTestCase

# Two pairs of points far apart: k-means with two clusters has one answer.
PAIRS = np.array([[0, 0], [0, 1], [10, 0], [10, 1]], dtype=np.float32)


def alive(pid):
    """The process exists and is not a zombie waiting for its parent."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


class LocalServerTest(unittest.TestCase):
    def test_a_client_without_address_runs_and_stops_its_own_server(self):
        client = mlclust.Client()
        local = client._local
        try:
            self.assertEqual(client.address, f"unix:{local.socket}")
            mode = stat.S_IMODE(os.stat(local.directory).st_mode)
            self.assertEqual(mode, 0o700)
            self.assertTrue(stat.S_ISSOCK(os.stat(local.socket).st_mode))
            h = client.cluster_points(PAIRS, algo="kmeans", clusters=2)
            np.testing.assert_array_equal(h.labels(2), [0, 0, 1, 1])
            self.assertEqual(mlclust.__version__, client.info().version)
            pid = local.process.pid
            self.assertTrue(alive(pid))
        finally:
            client.close()
        self.assertFalse(alive(pid))
        self.assertFalse(os.path.exists(local.directory))
        client.close()  # twice is harmless

    def test_with_block_and_garbage_collection_stop_it(self):
        with mlclust.Client() as client:
            pid, directory = client._local.process.pid, client._local.directory
            self.assertEqual(len(client.cluster_points(PAIRS, algo="hc", grid=4).levels), 4)
        self.assertFalse(alive(pid))
        self.assertFalse(os.path.exists(directory))
        client = mlclust.Client()
        pid, directory = client._local.process.pid, client._local.directory
        del client
        gc.collect()
        self.assertFalse(alive(pid))
        self.assertFalse(os.path.exists(directory))

    def test_interpreter_exit_stops_it(self):
        script = textwrap.dedent("""
            import mlclust
            client = mlclust.Client()  # never closed
            print(client._local.process.pid, client._local.directory, flush=True)
            mlclust.shared_client()    # the estimators' one, never closed either
            print(mlclust.shared_client()._local.process.pid, flush=True)
        """)
        result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                                timeout=120)
        self.assertEqual(result.returncode, 0, result.stderr)
        first, second = result.stdout.split("\n")[:2]
        pid, directory = first.split()
        for p in (int(pid), int(second)):
            self.assertFalse(alive(p), f"server {p} outlived the interpreter")
        self.assertFalse(os.path.exists(directory))

    def test_a_server_that_cannot_start_is_reported_with_its_words(self):
        with self.assertRaises(RuntimeError) as e:
            mlclust.Client(serve_args=["--workers", "999"])
        self.assertIn("exited with status 2", str(e.exception))
        self.assertIn("--workers: over 256", str(e.exception))
        missing = dict(os.environ, MLCLUST_BIN="/nonexistent/mlclust")
        script = "import mlclust\nmlclust.Client()\n"
        result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                                timeout=60, env=missing)
        self.assertNotEqual(result.returncode, 0)
        self.assertIn("FileNotFoundError: mlclust: MLCLUST_BIN=/nonexistent/mlclust is not an "
                      "executable file", result.stderr)


class RemoteAddressTest(ServedTestCase):
    def test_an_address_selects_that_server(self):
        with mlclust.Client(self.address) as client:
            self.assertIsNone(client._local)
            self.assertEqual(client.address, self.address)
            client.cluster_points(PAIRS, algo="kmeans", clusters=2)
            self.assertEqual(client.stats().jobs_succeeded, 1)


if __name__ == "__main__":
    unittest.main()
