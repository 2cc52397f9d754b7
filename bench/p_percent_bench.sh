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
bin="$(realpath "${1:?usage: p_percent_bench.sh ML_BENCH MESH_DIR [OUT_CSV]}")"
dir="${2:?usage: p_percent_bench.sh ML_BENCH MESH_DIR [OUT_CSV]}"
repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
out="${3:-$repo_root/bench/results/p_percent.csv}"
shift $(($# < 3 ? $# : 3))
meshes="bunny00 armadillo"
while [ $# -gt 0 ]; do
  case "$1" in
    --meshes) meshes="${2:?--meshes needs a list}"; shift 2 ;;
    *) echo "p_percent_bench: unknown argument '$1'" >&2; exit 2 ;;
  esac
done
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
echo "mesh,faces,energy,p_percent,p_rule,seconds,levels,k,clusters,energy_at_k,ml_energy_at_clusters,relative_to_ml" > "$out"
row() {  # row P RULE: ml_bench rows on stdin -> our rows, ML's energy from its curve
  awk -F, -v OFS=, -v p="$1" -v r="$2" -v curve="$tmp/ml.curve" -v ks="1000,200,50" '
    BEGIN { while ((getline line < curve) > 0) { split(line, f, ","); ml[f[1]] = f[2] }
            split(ks, k, ",") }
    { n++; e = ml[$11]; q = e > 0 ? sprintf("%.4f", $12 / e) : "nan"
      print $1, $2, $4, p, r, $9, $10, k[n], $11, $12, e, q }'
}
for mesh in $meshes; do
  # Each run to a file first: `row` reads ML's curve, which ml_bench writes at its end.
  "$bin" "$dir/$mesh.off" --algo ml --energy cvd --at 1000,200,50 --curve "$tmp/ml.curve" \
    > "$tmp/rows" 2> /dev/null
  row 0 - < "$tmp/rows" >> "$out"
  for p in 50 75 95; do
    for rule in sweep hc-first; do
      "$bin" "$dir/$mesh.off" --algo ml --energy cvd --p-percent "$p" --p-rule "$rule" \
        --at 1000,200,50 > "$tmp/rows" 2> /dev/null
      row "$p" "$rule" < "$tmp/rows" >> "$out"
    done
  done
done
echo "p_percent_bench: wrote $out" >&2
