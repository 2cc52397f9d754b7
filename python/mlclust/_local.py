"""The server that Client() with no address runs for its caller: the bundled `mlclust serve`
on a Unix socket in a private folder (mode 0700), stopped with the client, when it is
garbage collected, or at interpreter exit, whichever comes first.

The binary is MLCLUST_BIN where that is set (an error when it is not an executable file),
else the package's own bin/mlclust (pip install copies it there; the build tree links it),
else `mlclust` on PATH.
"""

import os
import shutil
import subprocess
import tempfile
import time
import weakref

import grpc

_START_SECONDS = 60.0  # the server's start (GL context included) takes well under this


def server_binary():
    """The path of the mlclust binary that a local server runs; FileNotFoundError naming
    the places looked at when there is none."""
    given = os.environ.get("MLCLUST_BIN")
    if given:
        if os.path.isfile(given) and os.access(given, os.X_OK):
            return given
        raise FileNotFoundError(f"mlclust: MLCLUST_BIN={given} is not an executable file "
                                "(unset it to run the package's own server)")
    tried = []
    bundled = os.path.join(os.path.dirname(os.path.abspath(__file__)), "bin", "mlclust")
    if os.access(bundled, os.X_OK):
        return bundled
    tried.append(bundled)
    on_path = shutil.which("mlclust")
    if on_path:
        return on_path
    tried.append("mlclust on PATH")
    raise FileNotFoundError("mlclust: no server binary to run in-process (looked at "
                            + ", ".join(tried) + "); install the package with pip, or give "
                            "Client() a server address")


def end_process(process, seconds=30.0):
    """Ends a server process if it still runs: SIGTERM (it drains for at most its
    --drain-seconds), then SIGKILL after `seconds` (also the tests' stop_server)."""
    if process.poll() is None:
        process.terminate()
        try:
            process.wait(timeout=seconds)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(timeout=seconds)


def _stop(process, directory, log):
    """Ends the server, then removes its folder. Safe to call twice."""
    end_process(process)
    log.close()
    shutil.rmtree(directory, ignore_errors=True)


class LocalServer:
    """`mlclust serve --listen unix:DIR/mlclust.sock` as a child process.

    address: the gRPC target ("unix:/tmp/mlclust-.../mlclust.sock"). stop() ends it (also
    run by garbage collection and at exit). `serve_args` are further `mlclust serve` flags
    (["--workers", "2"], ...).
    """

    def __init__(self, serve_args=()):
        binary = server_binary()
        self.directory = tempfile.mkdtemp(prefix="mlclust-")  # mode 0700: this user only
        os.chmod(self.directory, 0o700)
        self.socket = os.path.join(self.directory, "mlclust.sock")
        self.address = f"unix:{self.socket}"
        self.log_path = os.path.join(self.directory, "server.log")
        log = open(self.log_path, "w+")
        try:
            process = subprocess.Popen(
                [binary, "serve", "--listen", self.address, "--drain-seconds", "1",
                 *serve_args], stdin=subprocess.DEVNULL, stdout=log, stderr=log,
                start_new_session=True)  # Ctrl-C in a notebook interrupts the call, not it
        except BaseException:
            log.close()
            shutil.rmtree(self.directory, ignore_errors=True)
            raise
        self.process = process
        self._finalizer = weakref.finalize(self, _stop, process, self.directory, log)
        try:
            self._wait_until_serving(log)
        except BaseException:
            self.stop()
            raise

    def _wait_until_serving(self, log):
        deadline = time.monotonic() + _START_SECONDS
        while time.monotonic() < deadline:
            if self.process.poll() is not None:
                break
            if os.path.exists(self.socket):
                with grpc.insecure_channel(self.address) as channel:
                    try:
                        grpc.channel_ready_future(channel).result(timeout=1.0)
                        return
                    except grpc.FutureTimeoutError:
                        pass
            time.sleep(0.02)
        log.seek(0)
        said = log.read()[-2000:].strip()
        code = self.process.poll()
        raise RuntimeError("mlclust: the in-process server "
                           + (f"exited with status {code}" if code is not None
                              else f"did not answer within {_START_SECONDS:.0f} s")
                           + (f": {said}" if said else ""))

    @property
    def running(self):
        return self.process.poll() is None

    def stop(self):
        self._finalizer()
