#!/usr/bin/env bash
# Fig. 3.17: planar EMLO on fandisk from 70 random seeds with initial growth, then planar
# Δ_merging at 1 degree (the text: 70 -> 44 clusters). Seeds 1..RUNS.
#   bench/experiments/fig3_17_planar_merging.sh BUILD_DIR [RUNS] [OUT.csv]
set -euo pipefail
build=${1:?build dir}
runs=${2:-20}
out=${3:-bench/results/experiments/fig3_17_planar_merging.csv}
tmp=$(mktemp -d)
echo "seed,emlo_clusters,emlo_energy,merged_clusters,merges,merge_seconds" > "$out"
for seed in $(seq 1 "$runs"); do
  "$build/client/mlclust" mesh data/fandisk.off --algo emlo --energy planar --clusters 70 \
    --init random --seed "$seed" --labels "$tmp/labels.txt" --levels-csv "$tmp/levels.csv" \
    --quiet > /dev/null
  energy=$(tail -1 "$tmp/levels.csv" | cut -d, -f2)
  IFS=, read -r input output merges seconds < <("$build/bench/planar_merge" data/fandisk.off \
    "$tmp/labels.txt" --angle 1)
  echo "$seed,$input,$energy,$output,$merges,$seconds" | tee -a "$out"
done
rm -rf "$tmp"
