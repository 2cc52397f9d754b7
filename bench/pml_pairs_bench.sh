#!/usr/bin/env bash
# Mesh PML's pair rule, measured: for each mesh and energy, ML, PML with every mutual pair
# per level (Alg. 5.3, "all") and PML with the cheaper half ("cheaper-half"), PML to the
# end (no hand-over to ML), one thread. Energy at the first level with at most k clusters
# for k = 1000, 200, 50 (PML skips counts: `clusters` is the count that level has), and
# relative to ML's energy at that same count.
#
#   bench/pml_pairs_bench.sh ML_BENCH MESH_DIR [OUT_CSV] [--meshes "fandisk bunny00"]
#
# OUT_CSV (default bench/results/pml_pairs.csv):
#   mesh,faces,energy,algo,pml_pairs,seconds,levels,k,clusters,energy_at_k,
#   ml_energy_at_clusters,relative_to_ml
set -euo pipefail
# shellcheck source=bench/relative_to_ml.sh
source "$(dirname "${BASH_SOURCE[0]}")/relative_to_ml.sh"
relative_to_ml_init pml_pairs "fandisk bunny00 armadillo elephant" algo,pml_pairs "$@"
for mesh in $meshes; do
  for energy in cvd planar; do
    run_ml "$mesh" --energy "$energy" --threads 1
    row ml -
    for pairs in all cheaper-half; do
      run "$mesh" --algo pml --pml-pairs "$pairs" --energy "$energy" --threads 1
      row pml "$pairs"
    done
  done
done
echo "pml_pairs_bench: wrote $out" >&2
