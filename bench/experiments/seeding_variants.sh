#!/usr/bin/env bash
# Seeding variants of the dissertation (l. 671, 849, 1219) against our defaults, EMLO after
# each: energy before/after EMLO and the time of each step (best of 3).
#   bash bench/experiments/seeding_variants.sh > bench/results/experiments/seeding_variants.csv
# Needs build/bench/mesh_bench. Columns: mesh_bench's, plus variant,level.
set -euo pipefail
cd "$(dirname "$0")/../.."
B=build/bench/mesh_bench
echo "variant,level,$($B --header)"
run() {  # variant level mesh k energy [extra...]
  local variant=$1 level=$2 mesh=$3 k=$4 energy=$5; shift 5
  echo "$variant,$level,$($B "$mesh" --k "$k" --energy "$energy" --level "$level" --repeats 3 "$@")"
}
for spec in "data/fandisk.off 100 12" "data/fandisk.off 500 12" \
            "data/bench/bunny00.off 500 12" "data/bench/bunny00.off 2000 12"; do
  set -- $spec
  mesh=$1 k=$2 big=$3
  for energy in cvd planar; do
    for level in 0 2; do
      run flood+merge $level "$mesh" "$k" $energy
      run flood+reseed $level "$mesh" "$k" $energy --reduce reseed
      run free+merge $level "$mesh" "$k" $energy --growth free
      run free+reseed $level "$mesh" "$k" $energy --growth free --reduce reseed
    done
    run flood+add-seeds "$big" "$mesh" "$k" $energy --add-seeds
    run free+add-seeds "$big" "$mesh" "$k" $energy --add-seeds --growth free
    run random-flood 0 "$mesh" "$k" $energy --init random
    run random-free 0 "$mesh" "$k" $energy --init random --growth free
  done
done
