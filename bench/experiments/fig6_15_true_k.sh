#!/usr/bin/env bash
# Fig. 6.15: how many clusters X-means and ML (stopping where the BIC first decreases)
# find in N spherical Gaussians (sigma 1, 500 points each, centres uniform in
# [-25, 25]^3), DATASETS data sets per N (the text: 10).
#   bench/experiments/fig6_15_true_k.sh BUILD_DIR [DATASETS] [OUT.csv] [N ...]
# X-means (divisive_bench) from k_min = 1 (Alg. 2.5 as the text runs it from one cluster)
# and from k_min = N / 5, k_max = 2N; ML from the voxel-grid start (bic_direction): the
# BIC's maximum, its first decrease from few clusters to many (the server's
# bic_first_decrease) and its first decrease in the agglomerative direction (l. 2798).
set -euo pipefail
build=${1:?build dir}
datasets=${2:-3}
out=${3:-bench/results/experiments/fig6_15_true_k.csv}
shift $(( $# < 3 ? $# : 3 ))
ns=${*:-10 25 50 100 150 200 250}
tmp=$(mktemp -d)
echo "gaussians,dataset,xmeans_from_1,xmeans_from_n5,ml_start_clusters,ml_bic_max,ml_first_decrease_few_to_many,ml_first_decrease_agglomerative" > "$out"
for n in $ns; do
  for d in $(seq 1 "$datasets"); do
    /usr/bin/python3 bench/points_data.py --per-blob 500 --d 3 --blobs "$n" --seed "$((1000 * n + d))" \
      --out "$tmp/p.npy"
    x1=$("$build/bench/divisive_bench" --algo xmeans --input "$tmp/p.npy" --kmin 1 \
      --kmax $((2 * n)) --seed "$d" | sed 's/.*"clusters": \([0-9]*\).*/\1/')
    x5=$("$build/bench/divisive_bench" --algo xmeans --input "$tmp/p.npy" --kmin $((n / 5 > 0 ? n / 5 : 1)) \
      --kmax $((2 * n)) --seed "$d" | sed 's/.*"clusters": \([0-9]*\).*/\1/')
    ml=$("$build/bench/bic_direction" "$tmp/p.npy")
    echo "$n,$d,$x1,$x5,$ml" | tee -a "$out"
  done
done
rm -rf "$tmp"
