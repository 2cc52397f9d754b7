#!/usr/bin/env bash
# Fig. 5.15 again after the BB conflict-rule fix: BB and EMLO on bunny00, CVD, random seeds
# 1..RUNS, K = 2000, 1500, 1000, with each connectivity guard (ring: ours, the default;
# alg32: Alg. 3.2; off). One mesh_bench row per run, seeds in increasing order.
#   bash bench/experiments/fig5_15_guards.sh [RUNS] [GUARD_RUNS] > bench/results/experiments/fig5_15_guards.csv
set -euo pipefail
cd "$(dirname "$0")/../.."
B=build/bench/mesh_bench
RUNS=${1:-100}
GUARD_RUNS=${2:-20}
echo "guard,$($B --header)"
for k in 2000 1500 1000; do
  for guard in ring alg32 off; do
    runs=$RUNS
    [ "$guard" = ring ] || runs=$GUARD_RUNS
    for algo in emlo bb; do
      $B data/bench/bunny00.off --k $k --init random --seed 1 --runs "$runs" --algo $algo \
        --guard $guard --repeats 1 | sed "s/^/$guard,/"
    done
  done
done
