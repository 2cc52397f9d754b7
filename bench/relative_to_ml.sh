# shellcheck shell=bash
# Shared by bench/p_percent_bench.sh and bench/pml_pairs_bench.sh (sourced, not run):
# ml_bench runs whose energy at the first level with at most k clusters (k = 1000, 200, 50)
# is put against ML's energy at that same cluster count.
#
#   relative_to_ml_init NAME DEFAULT_MESHES COLUMN_A,COLUMN_B "$@"
#       parses "ML_BENCH MESH_DIR [OUT_CSV] [--meshes LIST]" into $bin, $dir, $out (default
#       bench/results/NAME.csv) and $meshes, makes $tmp (removed on exit) and writes the
#       header of OUT_CSV:
#         mesh,faces,energy,COLUMN_A,COLUMN_B,seconds,levels,k,clusters,energy_at_k,
#         ml_energy_at_clusters,relative_to_ml
#   run_ml MESH ARGS...  ml_bench on MESH with --algo ml ARGS, keeping ML's curve
#   run MESH ARGS...     ml_bench on MESH with ARGS
#   row A B              the last run's rows to OUT_CSV, A and B as COLUMN_A and COLUMN_B
# shellcheck disable=SC2034  # sets $bin, $dir, $out and $meshes for the caller
relative_to_ml_init() {
  local name="$1" usage="usage: $1_bench.sh ML_BENCH MESH_DIR [OUT_CSV]"
  meshes="$2"
  local columns="$3"
  shift 3
  bin="$(realpath "${1:?$usage}")"
  dir="${2:?$usage}"
  local repo_root
  repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
  out="${3:-$repo_root/bench/results/$name.csv}"
  shift $(($# < 3 ? $# : 3))
  while [ $# -gt 0 ]; do
    case "$1" in
      --meshes) meshes="${2:?--meshes needs a list}"; shift 2 ;;
      *) echo "${name}_bench: unknown argument '$1'" >&2; exit 2 ;;
    esac
  done
  tmp="$(mktemp -d)"
  trap 'rm -rf "$tmp"' EXIT
  echo "mesh,faces,energy,$columns,seconds,levels,k,clusters,energy_at_k,ml_energy_at_clusters,relative_to_ml" > "$out"
}

# Each run goes to a file first: `row` reads ML's curve, which ml_bench writes at its end.
run_ml() {
  local mesh="$1"
  shift
  "$bin" "$dir/$mesh.off" --algo ml "$@" --at 1000,200,50 --curve "$tmp/ml.curve" \
    > "$tmp/rows" 2> /dev/null
}

run() {
  local mesh="$1"
  shift
  "$bin" "$dir/$mesh.off" "$@" --at 1000,200,50 > "$tmp/rows" 2> /dev/null
}

# ml_bench's row: mesh,faces,algo,energy,optimizer,p_percent,pml_until,threads,seconds,
# levels,clusters,energy (at the first level with at most k clusters, k as asked in order).
row() {
  awk -F, -v OFS=, -v a="$1" -v b="$2" -v curve="$tmp/ml.curve" -v ks="1000,200,50" '
    BEGIN { while ((getline line < curve) > 0) { split(line, f, ","); ml[f[1]] = f[2] }
            split(ks, k, ",") }
    { n++; e = ml[$11]; r = e > 0 ? sprintf("%.4f", $12 / e) : "nan"
      print $1, $2, $4, a, b, $9, $10, k[n], $11, $12, e, r }' < "$tmp/rows" >> "$out"
}
