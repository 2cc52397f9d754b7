"""Load, fault and drain proof for `mlclust serve` (issue 12), with the Python client.

  PYTHONPATH=build/python /usr/bin/python3 bench/service_load.py MLCLUST_BINARY DATA_DIR

Starts its own servers on loopback ports and prints one block of figures per part:
  load   32 concurrent clients x 10 jobs on `serve --workers 2 --queue 8`: every accepted
         job's levels equal a solo run's, every refusal is RESOURCE_EXHAUSTED, nothing
         hangs (each call has a 300 s deadline); p50/p99 latency of accepted jobs.
  burst  20 client processes start big jobs and are killed mid-stream: the server's RSS
         once the jobs are gone, against its baseline after one such job.
  drain  SIGTERM with one job running and three queued: the running one finishes, the
         queued ones get UNAVAILABLE, every client returns.
"""

import os
import re
import signal
import subprocess
import sys
import threading
import time

import grpc
import numpy as np

import mlclust

BIN, DATA = sys.argv[1], sys.argv[2]
PARTS = sys.argv[3:] or ["load", "burst", "drain"]


def start_server(*flags):
    log = open(f"/tmp/service_load_{os.getpid()}_{time.time_ns()}.log", "w+")
    proc = subprocess.Popen([BIN, "serve", "--listen", "127.0.0.1:0", *flags],
                            stdout=log, stderr=log)
    for _ in range(600):
        log.seek(0)
        m = re.search(r"listening on port (\d+)", log.read())
        if m:
            return proc, f"127.0.0.1:{m.group(1)}", log
        time.sleep(0.05)
    raise RuntimeError("server did not start")


def rss_mib(pid):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS"):
                return int(line.split()[1]) / 1024
    return 0.0


def summary(h):
    """What must be equal between a loaded and a solo run: every level's count and energy,
    and the labels at three levels."""
    counts = [l.cluster_count for l in h.levels]
    energies = [l.energy for l in h.levels]
    picks = sorted({counts[0], counts[len(counts) // 2], counts[-1]})
    return counts, energies, [mlclust_labels(h, k) for k in picks]


def mlclust_labels(h, k):
    return np.asarray(h.labels(k)).tobytes()


def jobs():
    fandisk = mlclust.read_mesh(os.path.join(DATA, "fandisk.off"))
    elephant = mlclust.read_mesh(os.path.join(DATA, "elephant.off"))
    return [
        ("fandisk hc", fandisk, dict(algo="hc")),
        ("elephant ml", elephant, dict(algo="ml")),
        ("fandisk emlo 50", fandisk, dict(algo="emlo", clusters=50)),
        ("elephant hc", elephant, dict(algo="hc")),
    ]


def load():
    specs = jobs()
    proc, addr, log = start_server("--workers", "2", "--queue", "8")
    try:
        with mlclust.Client(addr) as client:
            solo = {name: summary(client.cluster_mesh(*mesh, **kw)) for name, mesh, kw in specs}
        results, lock = [], threading.Lock()

        def one_client(c):
            with mlclust.Client(addr) as client:
                for j in range(10):
                    name, mesh, kw = specs[(c + j) % len(specs)]
                    t0 = time.time()
                    try:
                        h = client.cluster_mesh(*mesh, timeout=300, **kw)
                        outcome = "ok" if summary(h) == solo[name] else "DIFFERENT"
                    except mlclust.Error as e:
                        outcome = e.code.name
                    with lock:
                        results.append((outcome, time.time() - t0))

        t0 = time.time()
        threads = [threading.Thread(target=one_client, args=(c,)) for c in range(32)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        wall = time.time() - t0
        with mlclust.Client(addr) as client:
            stats = client.stats()
        outcomes = {}
        for o, _ in results:
            outcomes[o] = outcomes.get(o, 0) + 1
        latency = np.array([s for o, s in results if o == "ok"])
        print(f"load: 32 clients x 10 jobs in {wall:.1f} s on --workers 2 --queue 8: {outcomes}; "
              f"accepted jobs' latency p50 {np.percentile(latency, 50):.2f} s, "
              f"p99 {np.percentile(latency, 99):.2f} s; server counted "
              f"{stats.jobs_succeeded} succeeded, {stats.jobs_rejected} rejected, "
              f"{stats.calls_refused} calls refused")
    finally:
        proc.terminate()
        proc.wait(timeout=60)


BURST_CLIENT = r"""
import sys, mlclust
v, f = mlclust.read_mesh(sys.argv[2])
with mlclust.Client(sys.argv[1]) as c:
    c.cluster_mesh(v, f, algo="hc", progress=lambda p: None)
"""


def burst():
    big = os.path.join(DATA, "bench", "armadillo.off")
    proc, addr, log = start_server("--workers", "2", "--queue", "32")
    try:
        env = dict(os.environ)
        vertices, faces = mlclust.read_mesh(big)
        with mlclust.Client(addr) as client:
            client.cluster_mesh(vertices, faces, algo="hc")  # warm-up: the baseline
        time.sleep(1)
        baseline = rss_mib(proc.pid)
        clients = [subprocess.Popen([sys.executable, "-c", BURST_CLIENT, addr, big], env=env)
                   for _ in range(20)]
        # Kill them once every job is accepted (running or queued) and streaming.
        with mlclust.Client(addr) as client:
            accepted_before = client.stats().jobs_accepted
            deadline = time.time() + 120
            while (client.stats().jobs_accepted < accepted_before + 20 and
                   time.time() < deadline):
                time.sleep(0.05)
            time.sleep(0.5)
            accepted = client.stats().jobs_accepted - accepted_before
        peak = rss_mib(proc.pid)
        for c in clients:
            c.kill()
        for c in clients:
            c.wait()
        with mlclust.Client(addr) as client:
            deadline = time.time() + 300
            while time.time() < deadline:
                s = client.stats()
                if s.jobs_running == 0 and s.queue_depth == 0 and s.calls_active == 0:
                    break
                time.sleep(0.2)
            # One more small job: trimming happens when a worker goes idle.
            client.cluster_mesh(*mlclust.read_mesh(os.path.join(DATA, "fandisk.off")), algo="hc")
            time.sleep(1)
            s = client.stats()
        after = rss_mib(proc.pid)
        print(f"burst: 20 clients on {os.path.basename(big)} ({len(faces)} faces) killed "
              f"mid-stream ({accepted} jobs accepted when killed): RSS baseline {baseline:.0f} MiB, during {peak:.0f} MiB, after "
              f"{after:.0f} MiB ({100 * (after - baseline) / baseline:+.1f}%); stats: "
              f"{s.jobs_accepted} accepted, {s.jobs_succeeded} succeeded, "
              f"{s.jobs_cancelled} cancelled, {s.jobs_failed} failed, "
              f"serving: {s.calls_active} calls active")
    finally:
        proc.terminate()
        proc.wait(timeout=60)


def drain():
    big = mlclust.read_mesh(os.path.join(DATA, "bench", "armadillo.off"))
    small = mlclust.read_mesh(os.path.join(DATA, "fandisk.off"))
    proc, addr, log = start_server("--drain-seconds", "60")
    outcomes, lock = {}, threading.Lock()

    def run(name, mesh):
        t0 = time.time()
        try:
            with mlclust.Client(addr) as client:
                client.cluster_mesh(*mesh, algo="hc", timeout=300)
            outcome = "ok"
        except mlclust.Error as e:
            outcome = f"{e.code.name}: {e.details}"
        with lock:
            outcomes[name] = (outcome, time.time() - t0)

    threads = [threading.Thread(target=run, args=("running", big))]
    threads[0].start()
    with mlclust.Client(addr) as client:
        while client.stats().jobs_running == 0:
            time.sleep(0.05)
    for i in range(3):
        threads.append(threading.Thread(target=run, args=(f"queued {i}", small)))
        threads[-1].start()
    with mlclust.Client(addr) as client:
        while client.stats().queue_depth < 3:
            time.sleep(0.05)
    t0 = time.time()
    proc.send_signal(signal.SIGTERM)
    for t in threads:
        t.join(timeout=120)
    proc.wait(timeout=120)
    print(f"drain: SIGTERM with 1 running, 3 queued; server exited after "
          f"{time.time() - t0:.1f} s (code {proc.returncode}); clients: " +
          "; ".join(f"{k}: {v[0]} ({v[1]:.1f} s)" for k, v in sorted(outcomes.items())) +
          f"; hung: {sum(t.is_alive() for t in threads)}")


for part in PARTS:
    {"load": load, "burst": burst, "drain": drain}[part]()
    sys.stdout.flush()
