#!/usr/bin/env bash
# Issue 26 item 5: how many clusters X-means finds from k_min = 1 and from k_min = N / 5
# (k_max = 2N) with Alg. 2.5's stop (--lookahead 0) and with the look-ahead's forced rounds
# (ours, 1..3), on N spherical Gaussians (sigma 1, 500 points each, centres uniform in
# [-25, 25]^3: Fig. 6.15's data), DATASETS data sets per N, one thread.
#   bench/experiments/xmeans_lookahead.sh BUILD_DIR [DATASETS] [OUT.csv] [N ...]
set -euo pipefail
build=${1:?build dir}
datasets=${2:-3}
out=${3:-bench/results/experiments/xmeans_lookahead.csv}
shift $(( $# < 3 ? $# : 3 ))
ns=${*:-10 25 50 100 150 200 250}
tmp=$(mktemp -d)
echo "gaussians,dataset,kmin,lookahead,clusters,rounds,seconds" > "$out"
for n in $ns; do
  for d in $(seq 1 "$datasets"); do
    /usr/bin/python3 bench/points_data.py --per-blob 500 --d 3 --blobs "$n" --seed "$((1000 * n + d))" \
      --out "$tmp/p.npy"
    for kmin in 1 $((n / 5 > 0 ? n / 5 : 1)); do
      for lookahead in 0 1 2 3; do
        json=$("$build/bench/divisive_bench" --algo xmeans --input "$tmp/p.npy" --kmin "$kmin" \
          --kmax $((2 * n)) --lookahead "$lookahead" --seed "$d" --threads 1)
        clusters=$(echo "$json" | sed 's/.*"clusters": \([0-9]*\).*/\1/')
        seconds=$(echo "$json" | sed 's/.*"seconds": \([0-9.]*\).*/\1/')
        rounds=$(echo "$json" | grep -o '\[[0-9]*, -' | wc -l)
        echo "$n,$d,$kmin,$lookahead,$clusters,$rounds,$seconds" | tee -a "$out"
      done
    done
  done
done
rm -rf "$tmp"
