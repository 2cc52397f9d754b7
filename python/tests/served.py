"""The one set-up of the Python tests that talk to a real server (`mlclust serve` on
loopback): python/tests/test_client.py, python/tests/test_replicas.py and
tests/client/progress_test.py.

    start_server(directory, name, *args) -> (process, log, "127.0.0.1:PORT")
    stop_server(process, log)
    ServedTestCase: one server per test class (cls.dir, cls.address); a subclass connects in
        connect() and closes in disconnect().
"""

import os
import re
import subprocess
import tempfile
import time
import unittest

from mlclust._local import end_process

BIN = os.environ.get("MLCLUST_BIN", "build/client/mlclust")
DATA = os.environ.get("MLCLUST_DATA", "data")


def start_server(directory, name="server", *args):
    """Starts `mlclust serve --listen 127.0.0.1:0 ARGS...` logging to DIRECTORY/NAME.log and
    waits (60 s at most) for the port it prints."""
    log = open(os.path.join(directory, f"{name}.log"), "w+")
    process = subprocess.Popen([BIN, "serve", "--listen", "127.0.0.1:0", *args],
                               stdout=log, stderr=log)
    deadline = time.time() + 60
    while time.time() < deadline:
        log.seek(0)
        match = re.search(r"listening on port (\d+)", log.read())
        if match:
            return process, log, f"127.0.0.1:{match.group(1)}"
        if process.poll() is not None:
            break
        time.sleep(0.05)
    log.seek(0)
    said = log.read()[-2000:]
    stop_server(process, log)
    raise RuntimeError(f"server {name} did not start: {said}")


def stop_server(process, log):
    """Ends the server (if it still runs) and closes its log."""
    end_process(process)
    log.close()


class ServedTestCase(unittest.TestCase):
    """One server for the test class: cls.dir (a scratch folder), cls.address."""

    server_args = ()

    @classmethod
    def connect(cls):
        """Set up the class's client(s) to cls.address."""

    @classmethod
    def disconnect(cls):
        """Close what connect() opened (also after a connect() that failed half way)."""

    @classmethod
    def setUpClass(cls):
        cls.dir = tempfile.TemporaryDirectory()
        try:
            cls.server, cls.log, cls.address = start_server(cls.dir.name, "server",
                                                            *cls.server_args)
            cls.connect()
        except BaseException:
            cls.tearDownClass()
            raise

    @classmethod
    def tearDownClass(cls):
        cls.disconnect()
        if hasattr(cls, "server"):
            stop_server(cls.server, cls.log)
        cls.dir.cleanup()
