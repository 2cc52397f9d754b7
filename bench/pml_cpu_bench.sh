#!/usr/bin/env bash
# PML on the CPU's cores against ML (BENCHMARKS.md, "Multi-core PML (CPU)"): per mesh, ML
# and PML then ML below --pml-until (EMLO in every level, and with parallel_optimisation;
# each also with the first 90% of the merges unoptimised, p% hc-first) on 1 thread and on
# all cores, interleaved, each run R times (pml_cpu_bench keeps the best
# wall time of its own R runs; here every configuration runs once per round so that load
# changes hit all alike). One CSV row per run.
#
#   bench/pml_cpu_bench.sh BUILD_DIR [--meshes "bunny00 armadillo armadillo_1m"]
#                          [--rounds 3] [--pml-until 2000] [--threads N]
set -euo pipefail
build="${1:?usage: pml_cpu_bench.sh BUILD_DIR [options]}"
shift
repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
meshes="bunny00 armadillo armadillo_1m"
rounds=3
until_k=2000
threads="$(nproc)"
while [ $# -gt 0 ]; do
  case "$1" in
    --meshes) meshes="${2:?}"; shift 2 ;;
    --rounds) rounds="${2:?}"; shift 2 ;;
    --pml-until) until_k="${2:?}"; shift 2 ;;
    --threads) threads="${2:?}"; shift 2 ;;
    *) echo "pml_cpu_bench: unknown argument '$1'" >&2; exit 2 ;;
  esac
done
bench="$build/bench/pml_cpu_bench"
header=--header
for mesh in $meshes; do
  path="$repo_root/data/bench/$mesh.off"
  [ -f "$path" ] || { echo "pml_cpu_bench: $path not found, skipped" >&2; continue; }
  for _ in $(seq "$rounds"); do
    "$bench" "$path" $header --algo ml --threads "$threads"
    header=
    for t in 1 "$threads"; do
      for p in 0 90; do
        "$bench" "$path" --algo pml --pml-until "$until_k" --threads "$t" --p-percent "$p" \
          --p-rule hc-first
        "$bench" "$path" --algo pml --pml-until "$until_k" --threads "$t" --p-percent "$p" \
          --p-rule hc-first --parallel-optimisation
      done
    done
  done
done
