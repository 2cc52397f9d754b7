"""The estimators against scikit-learn's KMeans and AgglomerativeClustering on the same data:
fit time and inertia (bench/pages/python-client.md).

    PYTHONPATH=build/python /usr/bin/python3 python/bench/estimators_bench.py \\
        [--m 10000] [--d 3] [--blobs 10] [--k 10] [--repeats 3] [--no-agglomerative]

Data: Gaussian blobs (centres uniform in [-25, 25]^d, sigma 1, seed 1), float64. Every fit
is timed end to end (ours: the in-process server started once before, then upload, the job,
the levels back, labels, centres and inertia in numpy; the median of --repeats). Inertia
is computed the same way for every estimator from its labels: the sum of squared distances
of the rows to their cluster's mean. ARI: adjusted Rand index against the blobs.
"""

import argparse
import statistics
import time
import warnings

import numpy as np
from sklearn.cluster import AgglomerativeClustering
from sklearn.cluster import KMeans as SklearnKMeans
from sklearn.metrics import adjusted_rand_score

import mlclust


def blobs(m, d, k, seed):
    rng = np.random.default_rng(seed)
    centres = rng.uniform(-25, 25, size=(k, d))
    truth = rng.integers(0, k, size=m)
    return centres[truth] + rng.normal(size=(m, d)), truth


def inertia(x, labels):
    total = 0.0
    for label in np.unique(labels):
        rows = x[labels == label]
        total += float(((rows - rows.mean(axis=0)) ** 2).sum())
    return total


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--m", type=int, default=10000)
    parser.add_argument("--d", type=int, default=3)
    parser.add_argument("--blobs", type=int, default=10)
    parser.add_argument("--k", type=int, default=10)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--no-agglomerative", action="store_true",
                        help="leave out Ward (O(m^2) memory)")
    args = parser.parse_args()
    x, truth = blobs(args.m, args.d, args.blobs, seed=1)
    k = args.k
    mlclust.shared_client()  # the in-process server, started before the timings
    models = [
        ("mlclust.MultilevelClustering(algorithm='ml')", mlclust.MultilevelClustering(k)),
        ("mlclust.MultilevelClustering(algorithm='pml')",
         mlclust.MultilevelClustering(k, algorithm="pml")),
        ("mlclust.MultilevelClustering(algorithm='hc')",
         mlclust.MultilevelClustering(k, algorithm="hc")),
        ("mlclust.LocalNeighboursKMeans", mlclust.LocalNeighboursKMeans(k)),
        ("mlclust.KMeans", mlclust.KMeans(k)),
        ("mlclust.XMeans(k_min=2) (finds its K)", mlclust.XMeans(k_min=2)),
        ("sklearn KMeans(n_init=1)", SklearnKMeans(k, n_init=1, random_state=1)),
        ("sklearn KMeans(n_init=10)", SklearnKMeans(k, n_init=10, random_state=1)),
    ]
    if not args.no_agglomerative:
        models.append(("sklearn AgglomerativeClustering(linkage='ward')",
                       AgglomerativeClustering(k, linkage="ward")))
    print(f"m={args.m} d={args.d} blobs={args.blobs} K={k}; fit seconds: median of "
          f"{args.repeats}")
    print("| estimator | fit (s) | K | inertia | inertia / sklearn KMeans(n_init=10) | ARI |")
    print("|---|---|---|---|---|---|")
    rows = []
    for name, model in models:
        seconds = []
        for _ in range(args.repeats):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                start = time.perf_counter()
                labels = model.fit_predict(x)
                seconds.append(time.perf_counter() - start)
        rows.append((name, statistics.median(seconds), len(np.unique(labels)),
                     inertia(x, labels), adjusted_rand_score(truth, labels)))
    reference = [r for r in rows if r[0] == "sklearn KMeans(n_init=10)"][0][3]
    for name, seconds, clusters, value, ari in rows:
        print(f"| {name} | {seconds:.3f} | {clusters} | {value:.1f} | {value / reference:.4f} | "
              f"{ari:.4f} |")


if __name__ == "__main__":
    main()
