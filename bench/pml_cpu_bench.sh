#!/usr/bin/env bash
# PML on the CPU's cores against ML (BENCHMARKS.md, "Multi-core PML (CPU)" and "Multi-core
# PML: the merges and moves in parallel"): per mesh, ML and PML then ML below --pml-until,
# with EMLO in every level, with parallel_optimisation's rounds, and with its independent
# moves (each also with the first 90% of the merges unoptimised, p% hc-first), on each
# thread count of --thread-list, interleaved, each run R times (pml_cpu_bench keeps the
# best wall time of its own R runs; here every configuration runs once per round so that
# load changes hit all alike). One CSV row per run (cpu_seconds: all threads' CPU time).
#
#   bench/pml_cpu_bench.sh BUILD_DIR [--meshes "bunny00 armadillo armadillo_1m"]
#                          [--rounds 3] [--pml-until 2000] [--thread-list "1 16"]
#                          [--stop-at 1000]
#
# Each round also runs --preset many-cores (pml's preset: p95, PML to max(stop-at, 1000),
# parallel rounds) per thread count, then the same with --face-order-steps never.
# --stop-at K ends each run at K clusters (the whole hierarchy by default: 1); on a 16-core
# node: bench/pml_cpu_bench.sh build --thread-list "1 2 4 8 16" --stop-at 1000
set -euo pipefail
build="${1:?usage: pml_cpu_bench.sh BUILD_DIR [options]}"
shift
repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
meshes="bunny00 armadillo armadillo_1m"
rounds=3
until_k=2000
thread_list="1 $(nproc)"
stop_at=1
while [ $# -gt 0 ]; do
  case "$1" in
    --meshes) meshes="${2:?}"; shift 2 ;;
    --rounds) rounds="${2:?}"; shift 2 ;;
    --pml-until) until_k="${2:?}"; shift 2 ;;
    --thread-list) thread_list="${2:?}"; shift 2 ;;
    --threads) thread_list="1 ${2:?}"; shift 2 ;;  # the former option: 1 and N
    --stop-at) stop_at="${2:?}"; shift 2 ;;
    *) echo "pml_cpu_bench: unknown argument '$1'" >&2; exit 2 ;;
  esac
done
bench="$build/bench/pml_cpu_bench"
all="${thread_list##* }"
header=--header
for mesh in $meshes; do
  path="$repo_root/data/bench/$mesh.off"
  [ -f "$path" ] || { echo "pml_cpu_bench: $path not found, skipped" >&2; continue; }
  for _ in $(seq "$rounds"); do
    "$bench" "$path" $header --algo ml --threads "$all" --stop-at "$stop_at"
    header=
    for t in $thread_list; do
      for p in 0 90; do
        for mode in "" "--parallel-optimisation" "--parallel-optimisation --independent-moves"; do
          # shellcheck disable=SC2086  # $mode is zero, one or two flags
          "$bench" "$path" --algo pml --pml-until "$until_k" --threads "$t" --p-percent "$p" \
            --p-rule hc-first --stop-at "$stop_at" $mode
        done
      done
      # The registry's pml preset many-cores (BENCHMARKS.md, "Multi-core PML: the preset").
      "$bench" "$path" --preset many-cores --threads "$t" --stop-at "$stop_at"
      # The same levels with the face-order rounds as the loop (the steps run from 4 threads
      # by default: BENCHMARKS.md, "The face-order rounds in parallel steps"); the CSV row
      # does not say which: this one always follows the one above.
      "$bench" "$path" --preset many-cores --threads "$t" --stop-at "$stop_at" \
        --face-order-steps never
    done
  done
done
