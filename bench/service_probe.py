"""Probes a running `mlclust serve` the way a hostile or broken client would.

  PYTHONPATH=build/python python3 bench/service_probe.py ADDR SCENARIO [args]

Scenarios (each prints one line of figures):
  stall BIG SMALL [ALGO]  a client submits BIG and stops reading after Accepted; 1 s later
                          a client runs SMALL (hc) with a 120 s deadline. Prints SMALL's
                          latency and outcome, and the stalled call's status once the
                          probe gives up on it (it never reads on its own).
  slow BIG SMALL [ALGO]   as stall, but the first client reads one event per 0.5 s.
  specs N MIB             N calls that send only a spec declaring MIB MiB and then wait;
                          prints how many got an answer (and which code) within 5 s.
  uploads N MIB           N calls that upload MIB-1 of MIB MiB and then stall; prints
                          their answers within 5 s. Read the server's memory meanwhile.
  cancel BIG ALGO DELAY   cancels a job on BIG (emlo/bb at K = 1000) DELAY s after it
                          starts; prints how long the worker took to be free.
"""

import sys
import threading
import time

import grpc
import numpy as np

from mlclust import _draco, meshio
from mlclust.v1 import mlclust_pb2 as pb
from mlclust.v1 import mlclust_pb2_grpc as pb_grpc

ALGOS = {"hc": pb.ALGORITHM_HC, "ml": pb.ALGORITHM_ML, "emlo": pb.ALGORITHM_EMLO,
         "bb": pb.ALGORITHM_BB}


def encode(path):
    vertices, faces = meshio.read_mesh(path)
    payload, code, message = _draco.encode_mesh(vertices, faces)
    if code != 0:
        raise SystemExit(f"encoding {path}: {message}")
    return payload, len(faces)


def requests(spec, payload, chunk=1 << 20, hold=None):
    spec.input_bytes = len(payload)
    for offset in range(0, len(payload), chunk):
        request = pb.RunRequest(chunk=payload[offset:offset + chunk])
        if offset == 0:
            request.spec.CopyFrom(spec)
        yield request
    if hold is not None:
        hold.wait()


def mesh_spec(algo, clusters=0):
    return pb.JobSpec(input_kind=pb.INPUT_KIND_DRACO_MESH, algorithm=ALGOS[algo],
                      energy=pb.ENERGY_CVD, clusters=clusters, label="probe")


def run_small(stub, payload, timeout=120.0):
    started = time.time()
    try:
        for event in stub.Run(requests(mesh_spec("hc"), payload), timeout=timeout):
            if event.HasField("failed"):
                return time.time() - started, f"failed {event.failed.code}: {event.failed.message}"
        return time.time() - started, "ok"
    except grpc.RpcError as e:
        return time.time() - started, f"{e.code().name}: {e.details()}"


def stall(addr, big, small, algo="hc", reader_delay=None):
    channel_a = grpc.insecure_channel(addr, options=[("grpc.max_receive_message_length", -1)])
    channel_b = grpc.insecure_channel(addr, options=[("grpc.max_receive_message_length", -1)])
    stub_a, stub_b = pb_grpc.ClusteringStub(channel_a), pb_grpc.ClusteringStub(channel_b)
    big_payload, big_faces = encode(big)
    small_payload, _ = encode(small)
    clusters = 1000 if algo == "emlo" else 0
    call = stub_a.Run(requests(mesh_spec(algo, clusters), big_payload), timeout=600)
    accepted = next(call)
    t0 = time.time()
    outcome = {}

    def slow_reader():
        try:
            for _ in call:
                time.sleep(reader_delay)
            outcome["a"] = "ok"
        except grpc.RpcError as e:
            outcome["a"] = f"{e.code().name}: {e.details()}"
        outcome["a_seconds"] = time.time() - t0

    if reader_delay is not None:
        threading.Thread(target=slow_reader, daemon=True).start()
    time.sleep(1.0)
    seconds, result = run_small(stub_b, small_payload)
    print(f"big job {accepted.accepted.job_id} ({big_faces} faces, {algo}); small job: "
          f"{seconds:.2f} s, {result}")
    if reader_delay is None:
        # Now read what the stalled call holds, to learn how it ended.
        try:
            n = 0
            for _ in call:
                n += 1
            outcome["a"] = f"ok after {n} events"
        except grpc.RpcError as e:
            outcome["a"] = f"{e.code().name}: {e.details()}"
        outcome["a_seconds"] = time.time() - t0
    else:
        while "a" not in outcome:
            time.sleep(0.1)
    print(f"big job's call: {outcome['a']} ({outcome['a_seconds']:.1f} s after Accepted)")


def spec_calls(addr, n, mib, upload_fraction=0.0):
    channel = grpc.insecure_channel(addr)
    stub = pb_grpc.ClusteringStub(channel)
    hold = threading.Event()
    answers = []
    lock = threading.Lock()
    declared = mib << 20
    sent = int(declared * upload_fraction)
    payload = b"\0" * sent

    def one():
        spec = pb.JobSpec(input_kind=pb.INPUT_KIND_DRACO_MESH, algorithm=pb.ALGORITHM_HC,
                          input_bytes=declared, label="probe")

        def reqs():
            first = pb.RunRequest()
            first.spec.CopyFrom(spec)
            yield first
            for offset in range(0, sent, 1 << 20):
                yield pb.RunRequest(chunk=payload[offset:offset + (1 << 20)])
            hold.wait()

        try:
            for event in stub.Run(reqs(), timeout=30):
                if event.HasField("failed"):
                    with lock:
                        answers.append(grpc.StatusCode(
                            [c for c in grpc.StatusCode if c.value[0] == event.failed.code][0]).name)
                    return
        except grpc.RpcError as e:
            with lock:
                answers.append(e.code().name)

    threads = [threading.Thread(target=one, daemon=True) for _ in range(n)]
    for t in threads:
        t.start()
    time.sleep(float(sys.argv[5]) if len(sys.argv) > 5 else 5.0)
    with lock:
        counts = {}
        for a in answers:
            counts[a] = counts.get(a, 0) + 1
    print(f"{n} calls declaring {mib} MiB, {sent >> 20} MiB sent each: "
          f"{len(answers)} answered within the wait {counts}")
    sys.stdout.flush()
    hold.set()


def cancel_latency(addr, big, algo, delay):
    """Cancels a job `delay` s after Accepted and times until no job runs (stats)."""
    channel = grpc.insecure_channel(addr, options=[("grpc.max_receive_message_length", -1)])
    stub = pb_grpc.ClusteringStub(channel)
    payload, faces = encode(big)
    clusters = 1000 if algo in ("emlo", "bb") else 0
    spec = mesh_spec(algo, clusters)
    call = stub.Run(requests(spec, payload), timeout=600)
    next(call)
    while not stub.GetStats(pb.GetStatsRequest()).jobs_running:
        time.sleep(0.01)
    time.sleep(delay)
    t0 = time.time()
    call.cancel()
    while stub.GetStats(pb.GetStatsRequest()).jobs_running:
        time.sleep(0.01)
    print(f"{algo} on {big} ({faces} faces) cancelled {delay} s after it started: the worker "
          f"was free {time.time() - t0:.2f} s after the cancel")


def main():
    addr, scenario = sys.argv[1], sys.argv[2]
    if scenario == "stall":
        stall(addr, sys.argv[3], sys.argv[4], *(sys.argv[5:6]))
    elif scenario == "slow":
        stall(addr, sys.argv[3], sys.argv[4], *(sys.argv[5:6]), reader_delay=0.5)
    elif scenario == "specs":
        spec_calls(addr, int(sys.argv[3]), int(sys.argv[4]))
    elif scenario == "uploads":
        spec_calls(addr, int(sys.argv[3]), int(sys.argv[4]),
                   upload_fraction=1 - 1 / int(sys.argv[4]))
    elif scenario == "cancel":
        cancel_latency(addr, sys.argv[3], sys.argv[4], float(sys.argv[5]))
    else:
        raise SystemExit(__doc__)


if __name__ == "__main__":
    main()
