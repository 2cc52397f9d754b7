#!/usr/bin/env bash
# Bisecting k-means (Alg. 2.7) and X-means (Alg. 2.5), ours against scikit-learn's
# BisectingKMeans, on 1M x 3 Gaussian blobs (100 blobs, sigma 1, centres in [-25, 25]^3).
#   bench/experiments/divisive_vs_sklearn.sh BUILD_DIR [OUT.jsonl] [M]
# One JSON object per run (divisive_bench.cc, sklearn_divisive.py). Runs one at a time.
set -euo pipefail
build=${1:?build dir}
out=${2:-bench/results/experiments/divisive_1m.jsonl}
m=${3:-1000000}
data=$(mktemp -d)/blobs.npy
/usr/bin/python3 bench/points_data.py --m "$m" --d 3 --blobs 100 --seed 1 --out "$data"
: > "$out"
for seed in 1 2 3; do
  for split in size energy; do
    "$build/bench/divisive_bench" --algo bisecting --input "$data" --k 100 --split "$split" \
      --seed "$seed" | tee -a "$out"
  done
  for strategy in largest_cluster biggest_inertia; do
    /usr/bin/python3 bench/experiments/sklearn_divisive.py "$data" --k 100 \
      --strategy "$strategy" --seed "$seed" | tee -a "$out"
  done
done
# X-means from k_min = 1 and from k_min = 20 (k_max 400).
for kmin in 1 20; do
  "$build/bench/divisive_bench" --algo xmeans --input "$data" --kmin "$kmin" --kmax 400 \
    | tee -a "$out"
done
rm -f "$data"
