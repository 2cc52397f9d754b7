"""A client with gRPC's default 4 MiB receive limit on a job whose levels are bigger.

  PYTHONPATH=build/python /usr/bin/python3 bench/service_4mib.py ADDR MESH [K]

Runs EMLO at K clusters (default 1000) on MESH (a file, or grid:N for an N x N grid) and prints the outcome, the largest
message the server sent (read with an unlimited client) and the time.
"""

import sys
import time

import grpc

import mlclust
from mlclust import _draco
from mlclust.v1 import mlclust_pb2 as pb
from mlclust.v1 import mlclust_pb2_grpc as pb_grpc

addr, path = sys.argv[1], sys.argv[2]
k = int(sys.argv[3]) if len(sys.argv) > 3 else 1000
if path.startswith("grid:"):  # an n x n grid of squares, two triangles each
    import numpy as np
    n = int(path[5:])
    xs, ys = np.meshgrid(np.arange(n + 1), np.arange(n + 1))
    vertices = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], axis=1).astype(np.float32)
    a = (np.arange(n)[None, :] + (n + 1) * np.arange(n)[:, None]).ravel()
    b, c = a + 1, a + n + 1
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([c, b, c + 1], 1)]).astype(np.uint32)
else:
    vertices, faces = mlclust.read_mesh(path)
t0 = time.time()
try:
    with mlclust.Client(addr) as client:  # gRPC's default limits
        h = client.cluster_mesh(vertices, faces, algo="emlo", clusters=k)
    outcome = f"ok: {len(h.levels)} levels, {len(set(h.labels(k).tolist()))} clusters"
except mlclust.Error as e:
    outcome = f"{e.code.name}: {e.details[:120]}"
seconds = time.time() - t0
# The same job with no limit, to see the messages' sizes.
payload, _, _ = _draco.encode_mesh(vertices, faces)
spec = pb.JobSpec(input_kind=pb.INPUT_KIND_DRACO_MESH, algorithm=pb.ALGORITHM_EMLO,
                  energy=pb.ENERGY_CVD, clusters=k, input_bytes=len(payload))
channel = grpc.insecure_channel(addr, options=[("grpc.max_receive_message_length", -1)])
raw = channel.stream_stream("/mlclust.v1.Clustering/Run",
                            request_serializer=pb.RunRequest.SerializeToString,
                            response_deserializer=None)


def requests():
    for offset in range(0, len(payload), 1 << 20):
        r = pb.RunRequest(chunk=payload[offset:offset + (1 << 20)])
        if offset == 0:
            r.spec.CopyFrom(spec)
        yield r


sizes = [len(m) for m in raw(requests())]
print(f"{path} ({len(faces)} faces), EMLO K={k}, default-limits client: {outcome} in "
      f"{seconds:.1f} s; {len(sizes)} messages, largest {max(sizes) / 2**20:.2f} MiB")
