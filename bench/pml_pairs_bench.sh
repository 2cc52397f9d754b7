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
bin="$(realpath "${1:?usage: pml_pairs_bench.sh ML_BENCH MESH_DIR [OUT_CSV]}")"
dir="${2:?usage: pml_pairs_bench.sh ML_BENCH MESH_DIR [OUT_CSV]}"
repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
out="${3:-$repo_root/bench/results/pml_pairs.csv}"
shift $(($# < 3 ? $# : 3))
meshes="fandisk bunny00 armadillo elephant"
while [ $# -gt 0 ]; do
  case "$1" in
    --meshes) meshes="${2:?--meshes needs a list}"; shift 2 ;;
    *) echo "pml_pairs_bench: unknown argument '$1'" >&2; exit 2 ;;
  esac
done
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
echo "mesh,faces,energy,algo,pml_pairs,seconds,levels,k,clusters,energy_at_k,ml_energy_at_clusters,relative_to_ml" > "$out"
# ml_bench's row: mesh,faces,algo,energy,optimizer,p_percent,pml_until,threads,seconds,
# levels,clusters,energy (at the first level with at most k clusters, k as asked in order).
row() {  # row ALGO PAIRS: ml_bench rows on stdin -> our rows, ML's energy from the curve
  awk -F, -v OFS=, -v a="$1" -v p="$2" -v curve="$tmp/ml.curve" -v ks="1000,200,50" '
    BEGIN { while ((getline line < curve) > 0) { split(line, f, ","); ml[f[1]] = f[2] }
            split(ks, k, ",") }
    { n++; e = ml[$11]; r = e > 0 ? sprintf("%.4f", $12 / e) : "nan"
      print $1, $2, $4, a, p, $9, $10, k[n], $11, $12, e, r }'
}
for mesh in $meshes; do
  for energy in cvd planar; do
    # Each run to a file first: `row` reads ML's curve, which ml_bench writes at its end.
    "$bin" "$dir/$mesh.off" --algo ml --energy "$energy" --threads 1 --at 1000,200,50 \
      --curve "$tmp/ml.curve" > "$tmp/rows" 2> /dev/null
    row ml - < "$tmp/rows" >> "$out"
    for pairs in all cheaper-half; do
      "$bin" "$dir/$mesh.off" --algo pml --pml-pairs "$pairs" --energy "$energy" --threads 1 \
        --at 1000,200,50 > "$tmp/rows" 2> /dev/null
      row pml "$pairs" < "$tmp/rows" >> "$out"
    done
  done
done
echo "pml_pairs_bench: wrote $out" >&2
