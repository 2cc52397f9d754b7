"""The in-process client's overhead against the engine alone (bench/pages/python-client.md).

    PYTHONPATH=build/python /usr/bin/python3 python/bench/inprocess_overhead.py \\
        --points-bench build/bench/points_bench [--m 100000] [--repeats 3]

The same points (Gaussian blobs, --m x 3, float32, saved as .npy) clustered by:
  engine:   points_bench --input X.npy (the core library called directly: no server, no
            gRPC; its own timer around the clustering);
  client:   mlclust.Client() with no address (the bundled server on a Unix socket, started
            once before the timings; its start is printed apart), cluster_points wall time:
            upload, queue, the same clustering, every level streamed back and assembled;
  estimator: the same job through mlclust.MultilevelClustering / mlclust.KMeans fit
            (labels of the level, centres and inertia computed in numpy on top).
Runs interleave (engine, client, estimator) `--repeats` times; medians are printed.
"""

import argparse
import os
import statistics
import subprocess
import tempfile
import time

import numpy as np

import mlclust


def blobs(m, d, k, seed):
    rng = np.random.default_rng(seed)
    centres = rng.uniform(-25, 25, size=(k, d))
    return (centres[rng.integers(0, k, size=m)] + rng.normal(size=(m, d))).astype(np.float32)


def engine_seconds(binary, path, algo, k):
    args = [binary, "--algo", algo, "--input", path, "--k", str(k)]
    if algo == "ml":
        args += ["--until", "1"]
    out = subprocess.run(args, capture_output=True, text=True, check=True).stdout
    # One CSV row: algo,m,d,blobs,k,grid,threads,seconds,... (bench/points_bench.cc).
    return float(out.strip().splitlines()[-1].split(",")[7])


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--points-bench", required=True)
    parser.add_argument("--m", type=int, default=100000)
    parser.add_argument("--d", type=int, default=3)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--k", type=int, default=100, help="k-means' K")
    args = parser.parse_args()
    x = blobs(args.m, args.d, 100, seed=1)
    with tempfile.TemporaryDirectory() as scratch:
        path = os.path.join(scratch, "blobs.npy")
        np.save(path, x)
        start = time.perf_counter()
        client = mlclust.Client()
        print(f"in-process server start: {time.perf_counter() - start:.3f} s")
        jobs = {"ml": (dict(algo="ml"), mlclust.MultilevelClustering(n_clusters=1)),
                "kmeans": (dict(algo="kmeans", clusters=args.k),
                           mlclust.KMeans(n_clusters=args.k))}
        times = {name: {"engine": [], "client": [], "running": [], "estimator": []}
                 for name in jobs}
        levels = {}
        for _ in range(args.repeats):
            for name, (spec, estimator) in jobs.items():
                times[name]["engine"].append(
                    engine_seconds(args.points_bench, path, name, args.k))
                start = time.perf_counter()
                h = client.cluster_points(x, **spec)
                times[name]["client"].append(time.perf_counter() - start)
                times[name]["running"].append(h.done.seconds_running)
                levels[name] = len(h)
                start = time.perf_counter()
                estimator.fit(x)
                times[name]["estimator"].append(time.perf_counter() - start)
        client.close()
        print(f"m={args.m} d={args.d}, medians of {args.repeats}")
        print("| job | levels | engine alone (s) | server's running (s) | client (s) | "
              "client / engine | estimator fit (s) | fit / engine |")
        print("|---|---|---|---|---|---|---|---|")
        for name in jobs:
            t = {key: statistics.median(values) for key, values in times[name].items()}
            print(f"| {name} | {levels[name]} | {t['engine']:.3f} | {t['running']:.3f} | "
                  f"{t['client']:.3f} | {t['client'] / t['engine']:.3f} | "
                  f"{t['estimator']:.3f} | {t['estimator'] / t['engine']:.3f} |")


if __name__ == "__main__":
    main()
