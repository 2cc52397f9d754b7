#!/usr/bin/python3
"""scikit-learn's BisectingKMeans on a point file, for bench/experiments/divisive_bench.

Runs under Debian's /usr/bin/python3 (python3-sklearn). Prints one JSON object: the peer,
options, seconds (fit only; the file is read before the clock starts), clusters and energy
(the sum of squared distances of the points to their cluster means, in float64, computed
here from the labels the same way for every run).

  sklearn_divisive.py FILE.npy --k 100 [--strategy biggest_inertia|largest_cluster]
                      [--init random|k-means++] [--n-init 1] [--seed 1]
"""
import argparse
import json
import os
import sys
import time

import numpy as np

# The energy as the point peers compute it (bench/peers/points_peers.py).
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "peers"))
from points_peers import energy_of  # noqa: E402


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("file")
    parser.add_argument("--k", type=int, default=100)
    parser.add_argument("--strategy", default="biggest_inertia")
    parser.add_argument("--init", default="random")
    parser.add_argument("--n-init", type=int, default=1)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()

    import sklearn
    from sklearn.cluster import BisectingKMeans

    points = np.load(args.file)
    model = BisectingKMeans(n_clusters=args.k, init=args.init, n_init=args.n_init,
                            bisecting_strategy=args.strategy, random_state=args.seed,
                            algorithm="lloyd")
    start = time.perf_counter()
    model.fit(points)
    seconds = time.perf_counter() - start
    print(json.dumps({
        "algo": f"scikit-learn {sklearn.__version__} BisectingKMeans",
        "strategy": args.strategy, "init": args.init, "n_init": args.n_init,
        "seed": args.seed, "m": int(len(points)), "seconds": round(seconds, 4),
        "clusters": int(len(np.unique(model.labels_))),
        "energy": energy_of(points, model.labels_),
        "inertia": float(model.inertia_),
    }))


if __name__ == "__main__":
    main()
