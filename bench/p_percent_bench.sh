#!/usr/bin/env bash
# p% ML, measured (section 4.5, Fig. 4.28 / Tables 4.4-4.5): ML, and p% ML for p = 50, 75,
# 95 with the first p% merged by Alg. 4.2's sweeps ("sweep") and by HC ("hc-first", ours),
# CVD, one thread. Energy at the first level with at most k clusters (k = 1000, 200, 50)
# over ML's at the same count, and the time of the whole hierarchy.
#
#   bench/p_percent_bench.sh ML_BENCH MESH_DIR [OUT_CSV] [--meshes "bunny00"]
#
# OUT_CSV (default bench/results/p_percent.csv):
#   mesh,faces,energy,p_percent,p_rule,seconds,levels,k,clusters,energy_at_k,
#   ml_energy_at_clusters,relative_to_ml
set -euo pipefail
# shellcheck source=bench/relative_to_ml.sh
source "$(dirname "${BASH_SOURCE[0]}")/relative_to_ml.sh"
relative_to_ml_init p_percent "bunny00 armadillo" p_percent,p_rule "$@"
for mesh in $meshes; do
  run_ml "$mesh" --energy cvd
  row 0 -
  for p in 50 75 95; do
    for rule in sweep hc-first; do
      run "$mesh" --algo ml --energy cvd --p-percent "$p" --p-rule "$rule"
      row "$p" "$rule"
    done
  done
done
echo "p_percent_bench: wrote $out" >&2
