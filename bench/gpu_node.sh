#!/usr/bin/env bash
# Takes the figures of issue 10's "Speed" section that exist so far, in one run, on a GPU
# node (NVIDIA H100/H200 with 16 cores; DEVELOPERS.md / docker/ say how to get there): the
# GPU stages against the CPU path on the same machine's cores, with the renderer named on
# every row. Writes bench/results/gpu_node_<host>.csv (appended: one block per run, each
# row a CSV line, blocks separated by a "# run" line with date, host, cores and renderer).
#
#   bench/gpu_node.sh                 # the GPU-node sizes (issue 10)
#   bench/gpu_node.sh --quick         # small sizes: what a 2-core machine on llvmpipe can run
#   BIN=build/bench bench/gpu_node.sh # use an existing build (default: build/bench, built
#                                     # with scripts/build.sh when missing)
#
# Figures taken (GPU vs the CPU stage on $THREADS cores, default: all):
#   BB decide per sweep and whole BB runs, CVD, k = 1000 and 10,000, on bunny00 and the
#     1M-face armadillo_1m (scripts/fetch-bench-meshes.sh)       -> issue: >= 20x per sweep
#   cluster sums of 10^6 elements of 5 doubles (the CVD face sums) against an fp64 loop
#   LN k-means, 10M 3-D points, k = 10,000, seconds per iteration -> issue: >= 20x
#   brute-force k-means (ours, GPU assignment) on the same points and k, per iteration, and
#     the PyTorch peer (bench/peers/torch_kmeans.py: chunked cdist + argmin) where torch
#     with CUDA is installed                                        -> issue: LN faster
#   PML full hierarchy for meshes, merges only, CVD, pair rules all and cheaper-half, on
#     bunny00, armadillo and armadillo_1m: the GPU's levels (gpu/stages/multilevel_gpu.h)
#     against the CPU engine's PML on $THREADS cores, same levels checked per level
#     (bench/pml_gpu_bench)                                         -> issue: 1M faces < 1 s
#   HC full hierarchy for meshes, merges only, CVD, on bunny00, armadillo and armadillo_1m:
#     the GPU's steps against the CPU engine's HC, same levels checked (bench/hc_gpu_bench)
#   PML with BB sweeps after each level (Alg. 5.7, --optimizer bb) against the CPU
#     engine's PML with its local BB
#   ML with BB sweeps after each merge (Alg. 5.6, pml_gpu_bench --algo ml --optimizer bb):
#     fandisk's whole hierarchy and bunny00's first 2,000 steps, against the CPU engine's ML
#     with its local BB
# Not taken yet, because the GPU stages do not exist yet: PML and ML with EMLO on the GPU, meshlet-sized levels, ML for points on the GPU (issue 10's
# other rows).
set -euo pipefail
repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$repo_root"
quick=0
[ "${1:-}" = "--quick" ] && quick=1
BIN="${BIN:-build/bench}"
THREADS="${THREADS:-$(nproc)}"
if [ ! -x "$BIN/gpu_stages_bench" ]; then
  CMAKE_CXX_COMPILER_LAUNCHER="${CMAKE_CXX_COMPILER_LAUNCHER:-}" bash scripts/build.sh
  BIN=build/bench
fi
bench="$BIN/gpu_stages_bench"
mkdir -p bench/results
out="bench/results/gpu_node_$(hostname -s).csv"
[ "$quick" = 1 ] && out="bench/results/gpu_stages_quick.csv"
renderer="$("$BIN/../gpu/mlclust-gpu-info" 2>/dev/null | grep -m1 -i renderer || echo "renderer: ?")"
{
  echo "# run $(date -u +%FT%TZ) host=$(hostname -s) cores=$(nproc) threads=$THREADS $renderer"
} | tee -a "$out"

run() { "$bench" "$@" --threads "$THREADS" | tee -a "$out"; }

if [ "$quick" = 1 ]; then
  meshes=(data/bench/fandisk.off data/bench/bunny00.off)
  ks=(100 1000)
  points=200000; point_k=1000; kmeans_points=100000; kmeans_k=100
else
  meshes=(data/bench/bunny00.off data/bench/armadillo_1m.off)
  ks=(1000 10000)
  points=10000000; point_k=10000; kmeans_points=10000000; kmeans_k=10000
fi
header=--header
for mesh in "${meshes[@]}"; do
  for k in "${ks[@]}"; do
    run bb "$mesh" --k "$k" --energy cvd --repeats 5 $header
    header=
  done
done
"$bench" sums --elements 1000000 --k "$point_k" --values 5 --header | tee -a "$out"
run lnkmeans --points "$points" --k "$point_k" --header
run kmeans --points "$kmeans_points" --k "$kmeans_k" --iterations 3 --header
if /usr/bin/env python3 -c "import torch, sys; sys.exit(0 if torch.cuda.is_available() else 1)" 2>/dev/null; then
  echo "stage,points,dims,k,iterations,seconds,seconds_per_iteration,inertia,device" | tee -a "$out"
  python3 bench/peers/torch_kmeans.py --points "$kmeans_points" --k "$kmeans_k" --iterations 3 | tee -a "$out"
else
  echo "# torch with CUDA not available: the PyTorch peer was not run" | tee -a "$out"
fi
# PML full hierarchy (merges only, CVD): GPU vs the CPU engine's PML on $THREADS cores.
if [ -x "$BIN/pml_gpu_bench" ]; then
  if [ "$quick" = 1 ]; then
    pml_meshes=(data/bench/fandisk.off data/bench/bunny00.off)
  else
    pml_meshes=(data/bench/bunny00.off data/bench/armadillo.off data/bench/armadillo_1m.off)
  fi
  header=--header
  for mesh in "${pml_meshes[@]}"; do
    for pairs in all cheaper-half; do
      "$BIN/pml_gpu_bench" "$mesh" --pairs "$pairs" --threads "$THREADS" --repeats 3 $header |
        tee -a "$out"
      header=
    done
  done
  # Alg. 5.7: PML with BB sweeps after each level (--optimizer bb), GPU vs the CPU engine's
  # PML with its local BB on $THREADS cores (the levels differ: the GPU sweeps every face).
  header=--header
  for mesh in "${pml_meshes[@]}"; do
    for pairs in all cheaper-half; do
      "$BIN/pml_gpu_bench" "$mesh" --pairs "$pairs" --optimizer bb --threads "$THREADS" \
        --repeats 3 $header | tee -a "$out"
      header=
    done
  done
  # For context: the CPU's PML as jobs run it by default (EMLO after each level), which the
  # GPU does not do yet (merges only).
  header=--header
  for mesh in "${pml_meshes[@]}"; do
    "$BIN/pml_cpu_bench" "$mesh" --algo pml --optimizer emlo --threads "$THREADS" $header |
      tee -a "$out"
    header=
  done
else
  echo "# $BIN/pml_gpu_bench missing: the PML rows were not taken" | tee -a "$out"
fi
# HC full hierarchy for meshes (merges only, CVD, one collapse per step, Alg. 5.6 without
# optimisation): the GPU's steps (gpu/stages/hierarchy_gpu.h) against the CPU engine's HC,
# same levels and energies checked per level (bench/hc_gpu_bench; the CPU engine's HC is
# sequential, so $THREADS does not apply).
if [ -x "$BIN/hc_gpu_bench" ]; then
  if [ "$quick" = 1 ]; then
    hc_meshes=(data/bench/fandisk.off data/bench/bunny00.off)
  else
    hc_meshes=(data/bench/bunny00.off data/bench/armadillo.off data/bench/armadillo_1m.off)
  fi
  header=--header
  for mesh in "${hc_meshes[@]}"; do
    "$BIN/hc_gpu_bench" "$mesh" --repeats 3 $header | tee -a "$out"
    header=
  done
else
  echo "# $BIN/hc_gpu_bench missing: the HC rows were not taken" | tee -a "$out"
fi
# ML with BB on the GPU (Alg. 5.6: one collapse, then BB sweeps over every face, per level):
# the GPU's steps (gpu/stages/multilevel_gpu.h, RunMultilevelGpu) against the CPU engine's
# ML with its local BB (sequential). A step is O(faces) on the GPU, so fandisk's whole
# hierarchy and bunny00's first 2,000 steps (BENCHMARKS.md "ML with BB on the GPU").
if [ -x "$BIN/pml_gpu_bench" ]; then
  if [ "$quick" = 1 ]; then
    ml_runs=("data/bench/fandisk.off --clusters 10946")
  else
    ml_runs=("data/bench/fandisk.off" "data/bench/bunny00.off --clusters 73408")
  fi
  header=--header
  for run in "${ml_runs[@]}"; do
    # shellcheck disable=SC2086  # the mesh and its options
    "$BIN/pml_gpu_bench" $run --algo ml --optimizer bb --threads "$THREADS" $header |
      tee -a "$out"
    header=
  done
else
  echo "# $BIN/pml_gpu_bench missing: the ML rows were not taken" | tee -a "$out"
fi
# CPU PML on this node's cores against ML (issue 10: "CPU PML->ML vs ML on 16 cores: at
# most a quarter of ML's time at energy within 2% at k = 1000"): bench/pml_cpu_bench.sh,
# every configuration (the pml preset many-cores included) on 1, 2, 4, 8 and all threads.
if [ -x "$BIN/pml_cpu_bench" ]; then
  cpu_out="bench/results/pml_cpu_$(hostname -s).csv"
  [ "$quick" = 1 ] && cpu_out="bench/results/pml_cpu_quick.csv"
  echo "# run $(date -u +%FT%TZ) host=$(hostname -s) cores=$(nproc)" | tee -a "$cpu_out"
  if [ "$quick" = 1 ]; then
    bash bench/pml_cpu_bench.sh "$BIN/.." --meshes "bunny00" --rounds 1 --thread-list "1 $THREADS" \
      --stop-at 1000 | tee -a "$cpu_out"
  else
    bash bench/pml_cpu_bench.sh "$BIN/.." --meshes "bunny00 armadillo armadillo_1m" --rounds 3 \
      --thread-list "1 2 4 8 $THREADS" --stop-at 1000 | tee -a "$cpu_out"
  fi
  echo "wrote $cpu_out"
fi
echo "wrote $out"

# ---------------------------------------------------------------------------------------
# Meshlet-sized patches (helper "meshlets"; BENCHMARKS.md "Meshlet-sized patches: ours
# against meshoptimizer and METIS"): K = faces / 124 on bunny00, armadillo and armadillo_1m,
# ours (BB preset patches) against meshopt_buildMeshlets and METIS k-way, with ML's energy
# at K. CPU only (the patches have no GPU stage): the row for a 16-core node. The peers are
# compiled in where libmeshoptimizer-dev and libmetis-dev were found at build time
# (scripts/install-deps.sh --bench); without them the table has ours alone.
if [ -x "$BIN/meshlets_bench" ]; then
  meshlets_out="bench/results/meshlets_$(hostname -s).csv"
  [ "$quick" = 1 ] && meshlets_out="bench/results/meshlets_quick.csv"
  meshlets_meshes=(data/bench/bunny00.off data/bench/armadillo.off data/bench/armadillo_1m.off)
  [ "$quick" = 1 ] && meshlets_meshes=(data/bench/fandisk.off data/bench/bunny00.off)
  echo "# run $(date -u +%FT%TZ) host=$(hostname -s) cores=$(nproc) threads=$THREADS" \
    | tee -a "$meshlets_out"
  "$BIN/meshlets_bench" "${meshlets_meshes[@]}" --repeats 5 --threads "$THREADS" \
    --sweeps 4,6,8 --ml --header | tee -a "$meshlets_out"
  echo "wrote $meshlets_out"
fi

# ---------------------------------------------------------------------------------------
# PML for points on the GPU (helper "gpupoints"; BENCHMARKS.md "PML for points on the
# GPU"): the whole hierarchy of 1,000 Gaussian blobs in 3-D (voxel start and every level on
# the GPU, merges only, gpu/stages/points_multilevel_gpu.h) against the CPU engine's PML
# with the same options on $THREADS cores, 10^5 to 10^6 points (issue 10's "1M 3-D points
# under 1 s on the GPU"; the GPU does PML, not ML: see BENCHMARKS.md). For context, the
# CPU's ML (LN k-means after each merge, as jobs run it) at 10^6 points.
if [ -x "$BIN/points_gpu_bench" ]; then
  points_out="bench/results/points_gpu_$(hostname -s).csv"
  [ "$quick" = 1 ] && points_out="bench/results/points_gpu_quick.csv"
  point_sizes=(100000 300000 1000000)
  [ "$quick" = 1 ] && point_sizes=(100000)
  echo "# run $(date -u +%FT%TZ) host=$(hostname -s) cores=$(nproc) threads=$THREADS" \
    | tee -a "$points_out"
  header=--header
  for m in "${point_sizes[@]}"; do
    for pairs in cheaper-half all; do
      "$BIN/points_gpu_bench" --m "$m" --d 3 --blobs 1000 --pairs "$pairs" \
        --threads "$THREADS" --repeats 3 $header | tee -a "$points_out"
      header=
    done
  done
  # PML with LN k-means inside the levels on the GPU (helper "gpupts2",
  # gpu/stages/points_optimise_gpu.h; the jobs' default optimizer) against the CPU's.
  for m in "${point_sizes[@]}"; do
    "$BIN/points_gpu_bench" --m "$m" --d 3 --blobs 1000 --pairs cheaper-half \
      --optimizer lnkmeans --threads "$THREADS" --repeats 3 | tee -a "$points_out"
  done
  if [ "$quick" = 0 ] && [ -x "$BIN/points_bench" ]; then
    "$BIN/points_bench" --algo ml --m 1000000 --d 3 --blobs 1000 --threads "$THREADS" \
      2>&1 | tee -a "$points_out"
  fi
  echo "wrote $points_out"
fi
