"""Hostile clients against a fresh `mlclust serve` on loopback (issue 24), with figures.

  PYTHONPATH=build/python /usr/bin/python3 bench/service_hostile.py BIN SCENARIO [N]
  BASELINE=1 ... with BIN from before issue 24 (no timeout flags then).

Each scenario starts `BIN serve` on 127.0.0.1 (GPU off, short timeouts so the run is
short: --upload-idle-seconds 5, --watch-idle-seconds 5), runs a good client (fandisk, ML,
50 clusters) alone, then again during the attack, and prints one line: the good job's
latency without and during the attack, the server's peak RSS (VmHWM) against its
budgets' sum, and when the attack's calls were ended.

  stalled N    N calls (one connection each) send a spec and 1 byte, then stall.
  watchers N   N watchers of one finished job (one connection each) never read.
  metrics N    N connections trickle a request to /metrics (a byte each 200 ms); a
               scrape's latency meanwhile.
Every loop is bounded; nothing but loopback is touched.
"""

import os
import re
import subprocess
import sys
import threading
import time
import socket

import grpc

from mlclust import _draco, meshio
from mlclust.v1 import mlclust_pb2 as pb
from mlclust.v1 import mlclust_pb2_grpc as pb_grpc

DATA = os.path.join(os.path.dirname(__file__), "..", "data")


def start_server(binary, *args):
    log = open(f"/tmp/service_hostile_{os.getpid()}.log", "w+")
    # BASELINE=1: a server from before issue 24 (main's), which has no such flags.
    timeouts = [] if os.environ.get("BASELINE") else ["--upload-idle-seconds", "5",
                                                       "--watch-idle-seconds", "5"]
    process = subprocess.Popen([binary, "serve", "--listen", "127.0.0.1:0", "--gpu", "off",
                                *timeouts, *args], stdout=log, stderr=log)
    for _ in range(600):
        log.seek(0)
        text = log.read()
        port = re.search(r"listening on port (\d+)", text)
        metrics = re.search(r"metrics on http://[^:]+:(\d+)/metrics", text)
        if port and ("--metrics" not in args or metrics):
            return process, int(port.group(1)), int(metrics.group(1)) if metrics else 0
        time.sleep(0.1)
    raise SystemExit(f"the server did not start: {text}")


def peak_rss_mib(process):
    with open(f"/proc/{process.pid}/status") as status:
        for line in status:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
    return -1


def channel(port):
    # A connection of its own (no shared subchannel).
    return grpc.insecure_channel(f"127.0.0.1:{port}",
                                 options=[("grpc.use_local_subchannel_pool", 1),
                                          ("grpc.max_receive_message_length", -1)])


def fandisk():
    vertices, faces = meshio.read_mesh(os.path.join(DATA, "fandisk.off"))
    payload, code, message = _draco.encode_mesh(vertices, faces)
    if code != 0:
        raise SystemExit(message)
    return payload


def grid(n):
    """A flat n x n grid of 2 n^2 triangles, as Draco bytes."""
    import numpy as np
    xs, ys = np.meshgrid(np.arange(n + 1, dtype=np.float32), np.arange(n + 1, dtype=np.float32))
    vertices = np.stack([xs.ravel(), ys.ravel(), np.zeros((n + 1) ** 2, np.float32)], axis=1)
    faces = []
    for y in range(n):
        for x in range(n):
            a = y * (n + 1) + x
            faces += [(a, a + 1, a + n + 2), (a, a + n + 2, a + n + 1)]
    payload, code, message = _draco.encode_mesh(vertices, np.array(faces, dtype=np.uint32))
    if code != 0:
        raise SystemExit(message)
    return payload


def requests(spec, payload):
    spec.input_bytes = len(payload)
    for offset in range(0, len(payload), 1 << 20):
        request = pb.RunRequest(chunk=payload[offset:offset + (1 << 20)])
        if offset == 0:
            request.spec.CopyFrom(spec)
        yield request


def spec(detach=False):
    return pb.JobSpec(input_kind=pb.INPUT_KIND_DRACO_MESH, algorithm=pb.ALGORITHM_ML,
                      energy=pb.ENERGY_CVD, clusters=50, label="good", detach=detach)


def good_job(port, payload, retry_for=60.0):
    """Seconds until a good job succeeded (retrying refusals for at most `retry_for` s),
    and how many tries it took."""
    started = time.time()
    tries = 0
    while True:
        tries += 1
        stub = pb_grpc.ClusteringStub(channel(port))
        code = grpc.StatusCode.OK
        try:
            for event in stub.Run(requests(spec(), payload), timeout=120):
                if event.final:
                    if event.HasField("failed"):
                        code = grpc.StatusCode.RESOURCE_EXHAUSTED \
                            if event.failed.code == grpc.StatusCode.RESOURCE_EXHAUSTED.value[0] \
                            else grpc.StatusCode.UNKNOWN
                    break
        except grpc.RpcError as error:
            code = error.code()
        if code == grpc.StatusCode.OK:
            return time.time() - started, tries
        if code != grpc.StatusCode.RESOURCE_EXHAUSTED or time.time() - started > retry_for:
            return float("nan"), tries
        time.sleep(0.2)


def stalled(binary, n):
    process, port, _ = start_server(binary)
    payload = fandisk()
    alone, _ = good_job(port, payload)
    ended = []
    release = threading.Event()

    def stall():
        stub = pb_grpc.ClusteringStub(channel(port))
        started = time.time()

        def hold():
            s = spec()
            s.input_bytes = 1 << 20
            yield pb.RunRequest(spec=s, chunk=b"x")
            release.wait(120)

        try:
            for _ in stub.Run(hold(), timeout=120):
                pass
        except grpc.RpcError as error:
            ended.append((time.time() - started, error.code().name))

    threads = [threading.Thread(target=stall) for _ in range(n)]
    for t in threads:
        t.start()
    time.sleep(1.0)  # the stalled calls hold their slots
    during, tries = good_job(port, payload)
    for t in threads:
        t.join(130)
    release.set()
    rss = peak_rss_mib(process)
    process.terminate()
    process.wait(60)
    codes = sorted(set(code for _, code in ended))
    print(f"stalled {n}: good job alone {alone:.2f} s, during the attack {during:.2f} s "
          f"({tries} tries: refused while the slots were held); attack calls ended after "
          f"{min(t for t, _ in ended):.1f}-{max(t for t, _ in ended):.1f} s ({', '.join(codes)}); "
          f"peak RSS {rss:.0f} MiB (budgets 7680 MiB)")


def watchers(binary, n):
    process, port, _ = start_server(binary, "--max-calls", "1024",
                                    "--max-calls-per-peer", "1024")
    payload = fandisk()
    alone, _ = good_job(port, payload)
    # The watched job: HC on a 200 x 200 grid (80,000 faces; a stream of many MiB, so a
    # watcher that does not read stalls the server's writes).
    big = pb.JobSpec(input_kind=pb.INPUT_KIND_DRACO_MESH, algorithm=pb.ALGORITHM_HC,
                     energy=pb.ENERGY_CVD, label="watched", detach=True)
    stub = pb_grpc.ClusteringStub(channel(port))
    accepted = next(iter(stub.Run(requests(big, grid(200)), timeout=60)))
    job_id = accepted.accepted.job_id
    for _ in range(600):  # the detached job ends
        jobs = stub.ListJobs(pb.ListJobsRequest(), timeout=10).jobs
        if jobs and jobs[0].state not in ("queued", "running"):
            break
        time.sleep(0.1)
    rss_before = peak_rss_mib(process)
    calls = []
    started = time.time()
    for _ in range(n):
        call = pb_grpc.ClusteringStub(channel(port)).Watch(pb.WatchRequest(job_id=job_id),
                                                           timeout=120)
        calls.append(call)  # never read
    time.sleep(1.0)
    during, _ = good_job(port, payload)
    ends, codes = [], {}
    for call in calls:
        try:
            for _ in call:
                pass
            codes["OK"] = codes.get("OK", 0) + 1
        except grpc.RpcError as error:
            codes[error.code().name] = codes.get(error.code().name, 0) + 1
        ends.append(time.time() - started)
    rss = peak_rss_mib(process)
    process.terminate()
    process.wait(60)
    print(f"watchers {n}: good job alone {alone:.2f} s, during the attack {during:.2f} s; "
          f"watch calls {codes}, all ended within {max(ends):.1f} s; peak RSS "
          f"{rss_before:.0f} -> {rss:.0f} MiB (unread-event budget 1024 MiB)")


def metrics(binary, n):
    process, port, metrics_port = start_server(binary, "--metrics", "127.0.0.1:0")
    def scrape():
        started = time.time()
        with socket.create_connection(("127.0.0.1", metrics_port), timeout=60) as s:
            s.sendall(b"GET /metrics HTTP/1.0\r\nHost: localhost\r\n\r\n")
            data = b""
            while chunk := s.recv(65536):
                data += chunk
        return time.time() - started, data.startswith(b"HTTP/1.1 200")
    alone, _ = scrape()
    slow = [socket.create_connection(("127.0.0.1", metrics_port)) for _ in range(n)]
    stop = threading.Event()
    def trickle():
        for i in range(150):
            if stop.is_set():
                return
            for s in slow:
                try:
                    s.send(b"G")
                except OSError:
                    pass
            time.sleep(0.2)
    thread = threading.Thread(target=trickle)
    thread.start()
    time.sleep(0.5)
    during, ok = scrape()
    stop.set()
    thread.join()
    for s in slow:
        s.close()
    process.terminate()
    process.wait(60)
    print(f"metrics {n}: a scrape alone {alone * 1000:.1f} ms, with {n} slow connections "
          f"{during * 1000:.1f} ms ({'200' if ok else 'no answer'})")


if __name__ == "__main__":
    if len(sys.argv) < 3:
        raise SystemExit(__doc__)
    binary, scenario = sys.argv[1], sys.argv[2]
    count = int(sys.argv[3]) if len(sys.argv) > 3 else 64
    {"stalled": stalled, "watchers": watchers, "metrics": metrics}[scenario](binary, count)
