"""How much the Python client adds to a job: end-to-end time of cluster_mesh against the
server's own running time, on a grid mesh.

    PYTHONPATH=build/python /usr/bin/python3 python/bench/bench_client.py --server HOST:PORT [--n 300]

(start the server with `build/client/mlclust serve --listen 127.0.0.1:50051`).
"""

import argparse
import time

import numpy as np

import mlclust


def grid(n):
    xs, ys = np.meshgrid(np.arange(n + 1), np.arange(n + 1))
    vertices = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], axis=1).astype(np.float32)
    a = (np.arange(n)[None, :] + (n + 1) * np.arange(n)[:, None]).ravel()
    b, c = a + 1, a + n + 1
    d = c + 1
    faces = np.stack([np.stack([a, b, c], 1), np.stack([c, b, d], 1)], 1).reshape(-1, 3)
    return vertices, faces


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--server", required=True)
    parser.add_argument("--n", type=int, default=300, help="grid of n x n squares")
    parser.add_argument("--algo", default="hc,ml")
    args = parser.parse_args()
    vertices, faces = grid(args.n)
    with mlclust.Client(args.server) as client:
        for algo in args.algo.split(","):
            start = time.perf_counter()
            h = client.cluster_mesh(vertices, faces, algo=algo)
            total = time.perf_counter() - start
            running = h.done.seconds_running
            print(f"{algo}: {len(faces)} faces, {len(h)} levels, {h.num_triplets} triplets: "
                  f"{total:.3f} s end to end, server running {running:.3f} s, "
                  f"client and wire {total - running:.3f} s "
                  f"({h.num_triplets / total / 1e6:.2f} M triplets/s end to end)")


if __name__ == "__main__":
    main()
