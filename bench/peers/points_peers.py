#!/usr/bin/python3
"""The point-clustering peers of the issue-5 benchmarks, on the same .npy files as ours.

Runs under Debian's /usr/bin/python3 (python3-sklearn, python3-fastcluster, python3-faiss,
python3-scipy; scripts/install-deps.sh --bench installs them). Prints one JSON object per
run on stdout. Energies are computed here the same way for every peer: the sum of squared
distances of the points to their cluster means, in float64.

  points_peers.py sklearn-kmeans FILE --k 1000 [--init kmeans++|random] [--seed S] [--tol T]
  points_peers.py fastcluster-ward FILE --ks 10,50,100
  points_peers.py faiss-kmeans FILE --k 1000 [--iterations 25] [--seed S]
  points_peers.py ward-bic FILE                     # Ward's hierarchy + the textbook BIC

Threads: the libraries' defaults (all cores) unless OMP_NUM_THREADS says otherwise.
"""
import argparse
import json
import sys
import time

import numpy as np


def energy_of(points, labels):
    """Sum of squared distances to the cluster means (float64)."""
    x = points.astype(np.float64)
    _, compact = np.unique(labels, return_inverse=True)
    k = compact.max() + 1
    counts = np.bincount(compact, minlength=k).astype(np.float64)
    sums = np.zeros((k, x.shape[1]))
    np.add.at(sums, compact, x)
    means = sums / counts[:, None]
    return float(((x - means[compact]) ** 2).sum())


def sklearn_kmeans(args, points):
    from sklearn.cluster import KMeans, kmeans_plusplus
    import sklearn

    start = time.perf_counter()
    if args.init == "kmeans++":
        centres, _ = kmeans_plusplus(points, args.k, random_state=args.seed)
    else:
        rng = np.random.default_rng(args.seed)
        centres = points[rng.choice(len(points), args.k, replace=False)]
    init_seconds = time.perf_counter() - start
    model = KMeans(n_clusters=args.k, init=centres, n_init=1, algorithm="lloyd",
                   max_iter=args.max_iterations, tol=args.tol, random_state=args.seed)
    start = time.perf_counter()
    model.fit(points)
    fit_seconds = time.perf_counter() - start
    return {
        "peer": f"scikit-learn {sklearn.__version__} KMeans(lloyd)",
        "init": args.init,
        "init_seconds": init_seconds,
        "iterate_seconds": fit_seconds,
        "iterations": int(model.n_iter_),
        "seconds_per_iteration": fit_seconds / max(int(model.n_iter_), 1),
        "total_seconds": init_seconds + fit_seconds,
        "inertia": float(model.inertia_),
        "energy": energy_of(points, model.labels_),
    }


def fastcluster_ward(args, points):
    import fastcluster
    from scipy.cluster.hierarchy import fcluster

    start = time.perf_counter()
    tree = fastcluster.linkage_vector(points.astype(np.float64), method="ward")
    seconds = time.perf_counter() - start
    energies = {}
    for k in (int(v) for v in args.ks.split(",")):
        labels = fcluster(tree, k, criterion="maxclust")
        energies[str(k)] = energy_of(points, labels)
    return {
        "peer": f"fastcluster {fastcluster.__version__} linkage_vector(ward)",
        "seconds": seconds,
        "energy_at_k": energies,
    }


def faiss_kmeans(args, points):
    import faiss

    kmeans = faiss.Kmeans(points.shape[1], args.k, niter=args.iterations, seed=args.seed,
                          verbose=False, max_points_per_centroid=len(points))
    start = time.perf_counter()
    kmeans.train(np.ascontiguousarray(points, dtype=np.float32))
    seconds = time.perf_counter() - start
    _, labels = kmeans.index.search(np.ascontiguousarray(points, dtype=np.float32), 1)
    return {
        "peer": "faiss Kmeans",
        "iterations": args.iterations,
        "seconds": seconds,
        "seconds_per_iteration": seconds / args.iterations,
        "energy": energy_of(points, labels.ravel()),
    }


def ward_bic(args, points):
    """Ward's full hierarchy, then the textbook spherical-Gaussian BIC at every K (as
    core/model_selection.h defines it) from 1 to --max-k: the K of the largest BIC."""
    import fastcluster
    from scipy.cluster.hierarchy import fcluster

    r, dims = points.shape
    tree = fastcluster.linkage_vector(points.astype(np.float64), method="ward")
    best_k, best_bic = 0, -np.inf
    for k in range(1, min(args.max_k, r - 1) + 1):
        labels = fcluster(tree, k, criterion="maxclust")
        sizes = np.bincount(labels)[1:].astype(np.float64)
        sizes = sizes[sizes > 0]
        kk = len(sizes)
        sse = energy_of(points, labels)
        s2 = sse / (dims * (r - kk))
        log_l = (np.sum(sizes * np.log(sizes / r)) - r * dims / 2 * np.log(2 * np.pi * s2)
                 - dims * (r - kk) / 2)
        p = (kk - 1) + dims * kk + 1
        bic = log_l - p / 2 * np.log(r)
        if bic > best_bic:
            best_k, best_bic = kk, bic
    return {"peer": "fastcluster ward + BIC", "best_k": best_k, "bic": best_bic}


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("peer", choices=["sklearn-kmeans", "fastcluster-ward", "faiss-kmeans",
                                         "ward-bic"])
    parser.add_argument("file", help="float32 or float64 .npy, m x d")
    parser.add_argument("--k", type=int, default=1000)
    parser.add_argument("--ks", default="10,50,100")
    parser.add_argument("--max-k", type=int, default=400)
    parser.add_argument("--init", choices=["kmeans++", "random"], default="kmeans++")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--tol", type=float, default=1e-4)
    parser.add_argument("--max-iterations", type=int, default=300)
    parser.add_argument("--iterations", type=int, default=25)
    args = parser.parse_args()
    points = np.load(args.file)
    if points.ndim != 2:
        sys.exit(f"{args.file}: expected a 2-D array, got shape {points.shape}")
    run = {"sklearn-kmeans": sklearn_kmeans, "fastcluster-ward": fastcluster_ward,
           "faiss-kmeans": faiss_kmeans, "ward-bic": ward_bic}[args.peer]
    result = run(args, points)
    result.update({"file": args.file, "m": int(points.shape[0]), "d": int(points.shape[1])})
    print(json.dumps(result))


if __name__ == "__main__":
    main()
