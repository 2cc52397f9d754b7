#!/usr/bin/env bash
# Runs a fixed set of jobs through an `mlclust` CLI and writes, per job, the levels CSV
# (cluster count and energy of every level, %.17g) and the labels at one level. Two
# builds compared with `diff -r` show whether a change altered any result; the wall time
# of each job goes to times.csv (for speed comparisons run two builds interleaved:
# --repeats N runs every job N times and keeps the best).
#
#   bench/levels_regression.sh CLI OUTDIR [--meshes "fandisk bunny00"] [--repeats 1]
#
# Meshes: data/fandisk.off and, where fetched (scripts/fetch-bench-meshes.sh), bunny00,
# armadillo and elephant from data/bench/. Points: the meshes' vertices as CSV (real,
# thin-surface point sets), written once into OUTDIR/points/.
set -euo pipefail
cli="$(realpath "${1:?usage: levels_regression.sh CLI OUTDIR}")"
out="${2:?usage: levels_regression.sh CLI OUTDIR}"
shift 2
repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
meshes="fandisk bunny00 armadillo elephant"
repeats=1
while [ $# -gt 0 ]; do
  case "$1" in
    --meshes) meshes="${2:?--meshes needs a list}"; shift 2 ;;
    --repeats) repeats="${2:?--repeats needs a number}"; shift 2 ;;
    *) echo "levels_regression: unknown argument '$1'" >&2; exit 2 ;;
  esac
done
mkdir -p "$out/points"
: > "$out/times.csv"

mesh_path() {
  for p in "$repo_root/data/$1.off" "$repo_root/data/bench/$1.off"; do
    [ -f "$p" ] && { echo "$p"; return; }
  done
}

# run NAME ARGS...: the job with --levels-csv and --labels into OUTDIR/NAME.*
run() {
  local name="$1" best="" t0 t1 dt
  shift
  for _ in $(seq "$repeats"); do
    t0=$(date +%s.%N)
    "$cli" "$@" --quiet --levels-csv "$out/$name.levels.csv" --labels "$out/$name.labels.txt" \
      > /dev/null
    t1=$(date +%s.%N)
    dt=$(echo "$t1 - $t0" | bc)
    if [ -z "$best" ] || [ "$(echo "$dt < $best" | bc)" = 1 ]; then best=$dt; fi
  done
  echo "$name,$best" >> "$out/times.csv"
}

for mesh in $meshes; do
  path="$(mesh_path "$mesh")"
  [ -n "$path" ] || { echo "levels_regression: $mesh not found, skipped" >&2; continue; }
  for energy in cvd planar; do
    run "$mesh.ml.$energy" mesh "$path" --algo ml --energy "$energy" --clusters 200
    run "$mesh.hc.$energy" mesh "$path" --algo hc --energy "$energy" --clusters 200
    run "$mesh.pml.$energy" mesh "$path" --algo pml --energy "$energy" --clusters 200 \
      --pml-until 1000
    run "$mesh.emlo.$energy" mesh "$path" --algo emlo --energy "$energy" --clusters 200
    run "$mesh.bb.$energy" mesh "$path" --algo bb --energy "$energy" --clusters 200 --threads 1
  done
  # The vertices as a point set (OFF: header, counts, then x y z per vertex).
  csv="$out/points/$mesh.csv"
  [ -f "$csv" ] || awk 'NR==2 { n = $1; next } NR > 2 && n > 0 { print $1 "," $2 "," $3; n-- }' \
    "$path" > "$csv"
  run "$mesh.points.ml" points "$csv" --algo ml --clusters 100
  run "$mesh.points.hc" points "$csv" --algo hc --clusters 100
  run "$mesh.points.pml" points "$csv" --algo pml --clusters 100
  run "$mesh.points.lnkmeans" points "$csv" --algo lnkmeans --clusters 100 --seed 3
done
echo "levels_regression: wrote $(ls "$out"/*.levels.csv | wc -l) jobs to $out"
