#!/usr/bin/env bash
# Takes the figures of issue 10's "Speed" section on a GPU node (NVIDIA H100/H200 with 16
# cores): the GPU stages against the CPU path on the same machine's cores, and the CPU's
# many-core rows, with the renderer named on every GPU row. One row after the other in
# PRIORITY ORDER (the issue's headline figures first), optionally under a time budget.
# CONTRIBUTING.md, "GPU-node figures", says how to take them with the device tool in one
# call (bench/device_bundle.sh here, bench/device_run.sh there); README.md, "Deploying", and
# docker/ say how to run the server on a node.
#
#   bench/gpu_node.sh                      # every row at the GPU-node sizes, no time limit
#   bench/gpu_node.sh --quick              # small sizes: what a 2-core machine on llvmpipe runs
#   bench/gpu_node.sh --part 1 --budget 480 --out DIR
#   bench/gpu_node.sh --dry-run [--quick] [--part 2]   # the rows, their estimates, nothing run
#
#   --part 1|2|3|all part 1: the headline rows, sized to fit one device call (~8 minutes with
#                    the set-up); parts 2 and 3: the rest, each sized for one more call;
#                    all (default): every row, in order
#   --budget S       seconds for all rows together: each row runs under `timeout` with what
#                    is left (at most 3x its estimate, or its estimate + 60 s), a row whose
#                    estimate does not fit is written "skipped: budget"
#   --out DIR        where the rows go: DIR/gpu_node.csv (every row's block: a "# row ID"
#                    line, its CSV header and rows) and DIR/gpu_node_status.tsv (one line
#                    per row: id, part, status, seconds, estimate), appended row by row, so
#                    a kill loses nothing written (default: bench/results/gpu_node_<host>.csv
#                    or gpu_node_quick.csv, and the same name with _status.tsv)
#   --build DIR      the build tree holding bench/ and gpu/ (default build; built with
#                    scripts/build.sh when missing); BIN=DIR/bench as before also works
#   --threads N      the CPU stages' threads (default: all cores)
#   --only ID,ID     just these rows
#   --list-binaries  the binaries the rows use (bench/device_bundle.sh bundles them)
#   --check-guards   the rows this build's binaries would skip (a missing binary, mode or
#                    flag), torch aside; bench/device_bundle.sh prints them as warnings
#
# Estimates: each row carries two, in seconds: on a GPU node (16 cores, H100/H200) and with
# --quick on a 2-core machine with llvmpipe. The quick ones were measured (bench/
# device_run.sh --quick, BENCHMARKS.md "Taking the GPU-node figures in one device call");
# the GPU-node ones are extrapolated from this machine's full-size runs (the basis is
# printed by --dry-run): CPU work at 4-8x on 16 cores where it is parallel, 1.5-2x where it
# is sequential, GPU passes at 20x llvmpipe or more. Each part sums to at most 480 s
# (tests/bench/device_scripts_test.sh).
#
# Rows given by other engineers' tasks (points HC/ML on the GPU, growth on the GPU, points
# ML on many cores) run only where the binary has their mode or flag (the "guard" column): a
# binary built before that work is merged skips them as "skipped: no 'STRING' in BINARY".

# shellcheck disable=SC2016  # the rows' commands expand in bash -c, not here
set -euo pipefail
repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$repo_root"

quick=0 part=all budget="" out_dir="" build_dir="" dry_run=0 only="" list_binaries=0
check_guards=0
THREADS="${THREADS:-$(nproc)}"
while [ $# -gt 0 ]; do
  case "$1" in
    --quick) quick=1; shift ;;
    --part) part="${2:?}"; shift 2 ;;
    --budget) budget="${2:?}"; shift 2 ;;
    --out) out_dir="${2:?}"; shift 2 ;;
    --build) build_dir="${2:?}"; shift 2 ;;
    --threads) THREADS="${2:?}"; shift 2 ;;
    --only) only=",${2:?},"; shift 2 ;;
    --dry-run) dry_run=1; shift ;;
    --list-binaries) list_binaries=1; shift ;;
    --check-guards) check_guards=1; shift ;;
    -h | --help) awk 'NR > 1 && !/^#/ { exit } NR > 1 { sub(/^# ?/, ""); print }' "$0"; exit 0 ;;
    *) echo "gpu_node: unknown argument '$1'" >&2; exit 2 ;;
  esac
done
case "$part" in 1 | 2 | 3 | all) ;; *) echo "gpu_node: --part is 1, 2, 3 or all" >&2; exit 2 ;; esac
if [ -n "$budget" ] && ! [[ "$budget" =~ ^[0-9]+$ ]]; then
  echo "gpu_node: --budget takes whole seconds" >&2
  exit 2
fi
if [ -z "$build_dir" ]; then
  if [ -n "${BIN:-}" ]; then build_dir="$BIN/.."; else build_dir=build; fi
fi
BIN="$build_dir/bench"
M="${MESHES:-data/bench}"  # the meshes (bench/device_run.sh points it at its own)
export BIN M THREADS

# --- The sizes ------------------------------------------------------------------------
if [ "$quick" = 1 ]; then
  MESH_1M=bunny00 MESH_MID=fandisk MESH_SMALL=fandisk
  K_LOW=100 K_HIGH=1000
  LN_POINTS=200000 LN_K=1000 KM_POINTS=100000 KM_K=100
  POINTS_1M=100000 POINTS_MID=50000 POINTS_GPU_ML=10000 POINTS_GPU_ML_MID=10000 POINTS_GPU_ML_1M=20000
  POINTS_GPU_HC=10000 POINTS_GPU_PML_UNTIL=20000
  POINTS_HASH=fee37f0eb420da64 POINTS_HASH_BOUNDED=2352d100b86f59b5
  GROWTH_1M=bunny00 GROWTH_K=1000 GROWTH_PATCHES=608
  ML_RUN_A="$M/fandisk.off --clusters 10946" ML_RUN_B=""
else
  MESH_1M=armadillo_1m MESH_MID=armadillo MESH_SMALL=bunny00
  K_LOW=1000 K_HIGH=10000
  LN_POINTS=10000000 LN_K=10000 KM_POINTS=10000000 KM_K=10000
  POINTS_1M=1000000 POINTS_MID=300000 POINTS_GPU_ML=100000 POINTS_GPU_ML_MID=300000 POINTS_GPU_ML_1M=1000000
  POINTS_GPU_HC=1000000 POINTS_GPU_PML_UNTIL=1000000
  POINTS_HASH=7a96f446597992b4 POINTS_HASH_BOUNDED=4506abff75850083
  GROWTH_1M=armadillo_1m GROWTH_K=1000 GROWTH_PATCHES=6709
  ML_RUN_A="$M/fandisk.off" ML_RUN_B="$M/bunny00.off --clusters 73408"
fi
export MESH_1M MESH_MID MESH_SMALL K_LOW K_HIGH LN_POINTS LN_K KM_POINTS KM_K POINTS_1M \
  POINTS_MID ML_RUN_A ML_RUN_B POINTS_GPU_ML POINTS_GPU_ML_MID POINTS_GPU_ML_1M POINTS_GPU_HC \
  POINTS_GPU_PML_UNTIL POINTS_HASH POINTS_HASH_BOUNDED GROWTH_1M GROWTH_K GROWTH_PATCHES
# points_ml THREADS [--bounded F]: the CPU's ML on $POINTS_1M points (points_bench's own
# blobs), wall and user seconds (bash's time: the device may have no /usr/bin/time) and the
# hash over every level, which must equal the one-thread hash (fails the row otherwise).
points_ml() {
  local threads="$1" want="$POINTS_HASH" output
  shift
  [ "$*" = "--bounded 0.03" ] && want="$POINTS_HASH_BOUNDED"
  echo "algo,m,d,blobs,k,grid,threads,seconds,init_seconds,steps,energy,start_clusters"
  output="$({ TIMEFORMAT="wall_s=%R user_s=%U"; time "$BIN/points_bench" --algo ml \
    --m "$POINTS_1M" --blobs 1000 --threads "$threads" --fingerprint 1 "$@"; } 2>&1)"
  sed '/^ml,/!s/^/# /; /^# $/d' <<<"$output"  # the CSV row; the rest as comments
  grep -q "hash=$want" <<<"$output" || { echo "# hash is not $want" >&2; return 1; }
}
export -f points_ml

# --- The rows, in priority order ------------------------------------------------------
# row PART ID NODE_S QUICK_S GUARD BASIS COMMAND
#   NODE_S / QUICK_S: estimated seconds on a GPU node / with --quick on 2 cores + llvmpipe.
#   GUARD: BINARY (must exist in $BIN), BINARY:STRING (and the binary must contain STRING:
#   take a piece of the usage text of a mode or flag added by later work, e.g. "[--pml-until
#   N]", not a bare name that messages may hold), torch (python3 with torch and CUDA), or -.
#   BASIS: where NODE_S comes from (2-core figures of BENCHMARKS.md / this machine).
#   COMMAND: run with bash -c; $BIN, $M, $THREADS and the sizes above are exported. Its
#   stdout is the row's CSV block (each command prints its own header).
ids=() parts=() node_est=() quick_est=() guards=() bases=() commands=()
row() {
  parts+=("$1") ids+=("$2") node_est+=("$3") quick_est+=("$4") guards+=("$5") bases+=("$6")
  commands+=("$7")
}

# Part 1: the issue's headline figures.
row 1 pml-gpu-1m-all 15 6 pml_gpu_bench \
  "2 cores (loaded): CPU 13.4 s, llvmpipe 22.3 s; 16 cores ~3 s, GPU ~2 s, reading the mesh ~3 s" \
  '"$BIN/pml_gpu_bench" "$M/$MESH_1M.off" --pairs all --threads "$THREADS" --repeats 1 --header'
row 1 pml-gpu-1m-cheaper-half 15 8 pml_gpu_bench \
  "as pml-gpu-1m-all (cheaper-half: one host round trip per level more)" \
  '"$BIN/pml_gpu_bench" "$M/$MESH_1M.off" --pairs cheaper-half --threads "$THREADS" --repeats 1 --header'
row 1 bb-small-klow 5 2 gpu_stages_bench \
  "bunny00 k=1000: 2 cores CPU run 0.085 s, llvmpipe 0.27 s; decide best of 5" \
  '"$BIN/gpu_stages_bench" bb "$M/$MESH_SMALL.off" --k "$K_LOW" --energy cvd --threads "$THREADS" --repeats 5 --header'
row 1 bb-small-khigh 5 2 gpu_stages_bench \
  "bunny00 k=10000: as k=1000" \
  '"$BIN/gpu_stages_bench" bb "$M/$MESH_SMALL.off" --k "$K_HIGH" --energy cvd --threads "$THREADS" --repeats 5 --header'
row 1 bb-1m-klow 20 8 gpu_stages_bench \
  "armadillo_1m k=1000, 2 cores (load 10): CPU run 15.7 s (200 sweeps), llvmpipe 46 s, process 17.6 CPU-s; 16 cores /4, GPU /20, seeding + mesh ~4 s" \
  '"$BIN/gpu_stages_bench" bb "$M/$MESH_1M.off" --k "$K_LOW" --energy cvd --threads "$THREADS" --repeats 5 --header'
row 1 bb-1m-khigh 20 6 gpu_stages_bench \
  "armadillo_1m k=10000, 2 cores (load 10): CPU 9.0 s (107 sweeps), llvmpipe 24.3 s, 9.1 CPU-s" \
  '"$BIN/gpu_stages_bench" bb "$M/$MESH_1M.off" --k "$K_HIGH" --energy cvd --threads "$THREADS" --repeats 5 --header'
row 1 lnkmeans-10m 60 10 gpu_stages_bench \
  "1M points k=10000 on 2 cores (load 10): CPU 25.3 s (71 iterations), llvmpipe 74 s, 23.8 CPU-s; x10 points, CPU /8 (apply and refresh sequential), GPU /20" \
  '"$BIN/gpu_stages_bench" lnkmeans --points "$LN_POINTS" --k "$LN_K" --threads "$THREADS" --header'
row 1 torch-kmeans-10m 20 0 torch \
  "PyTorch import + CUDA start ~10 s, 3 chunked cdist iterations on 10M x 10k ~2 s" \
  'env -u LD_LIBRARY_PATH python3 bench/peers/torch_kmeans.py --points "$KM_POINTS" --k "$KM_K" --iterations 3 | sed "1istage,points,dims,k,iterations,seconds,seconds_per_iteration,inertia,device"'
row 1 kmeans-10m 60 4 gpu_stages_bench \
  "1M points k=1000 on 2 cores (load 10): CPU 0.51 s/iteration, 32.9 CPU-s with llvmpipe; x100 work, /12 on 16 cores: ~13 s, k-means++ seeding ~one iteration, GPU ~10 s" \
  '"$BIN/gpu_stages_bench" kmeans --points "$KM_POINTS" --k "$KM_K" --iterations 3 --threads "$THREADS" --header'
row 1 cpu-pml-ml-small 6 2 pml_cpu_bench \
  "bunny00 to k=1000: ML 2.2 s and the preset many-cores ~1 s on 2 cores" \
  'for a in "--algo ml" "--preset many-cores"; do "$BIN/pml_cpu_bench" "$M/$MESH_SMALL.off" $a --threads "$THREADS" --stop-at 1000 ${h---header}; h=; done'
row 1 cpu-pml-ml-1m 45 12 pml_cpu_bench \
  "armadillo_1m to k=1000: ML 41.5 s on 2 loaded cores (sequential: ~20 s on an idle core), preset 8-11 CPU-s /4, two mesh reads" \
  'for a in "--algo ml" "--preset many-cores"; do "$BIN/pml_cpu_bench" "$M/$MESH_1M.off" $a --threads "$THREADS" --stop-at 1000 ${h---header}; h=; done'
row 1 points-ml-1m-cpu 25 10 points_bench \
  "1M points ML, 16 threads: 48-52 s on one thread, 16-core bound ~11.7 s (BENCHMARKS.md, ML for 1M points on many cores); the levels' hash must be $POINTS_HASH" \
  'points_ml "$THREADS"'
row 1 points-pml-gpu-1m 20 4 points_gpu_bench \
  "1M points PML merges only on 2 cores: CPU 7.9 s, llvmpipe 44 s (BENCHMARKS.md); CPU /4, GPU /20, data ~1 s" \
  '"$BIN/points_gpu_bench" --m "$POINTS_1M" --d 3 --blobs 1000 --pairs cheaper-half --threads "$THREADS" --repeats 1 --header'

# Handed over by the engineers of issue 10's other parts (growth on the GPU, points HC/ML on
# the GPU, points ML on many cores); their binaries' new modes are guarded: built before
# that work is merged, the rows skip.
row 1 growth-1m 10 3 "gpu_stages_bench:growth MESH" \
  "initial growth (Fig. 5.9) K=1000 on armadillo_1m, GPU vs CPU rounds vs flood, then BB from each: 7.6 s on 2 loaded cores (BB dominates), ~5 s on the node" \
  '"$BIN/gpu_stages_bench" growth "$M/$GROWTH_1M.off" --k "$GROWTH_K" --threads "$THREADS" --header'
row 1 points-ml-1m-cpu-1thread 50 10 points_bench \
  "points-ml-1m-cpu on one thread, for the speed-up: 48-52 s (BENCHMARKS.md)" \
  'points_ml 1'
row 1 points-pml-until-gpu-1m 40 15 "points_gpu_bench:[--pml-until N]" \
  "points PML then ML below 1000 (LN k-means) on the GPU at 1M, the route to the issue's ML row: ~73 PML levels + 1,000 steps; 10^5 on 2 cores: llvmpipe 24 s, CPU 3.3 s; x10 points, CPU /4, GPU /20" \
  '"$BIN/points_gpu_bench" --m "$POINTS_GPU_PML_UNTIL" --d 3 --blobs 1000 --algo pml --optimizer lnkmeans --pml-until 1000 --threads "$THREADS" --header'
row 1 points-ml-gpu-100k 30 15 "points_gpu_bench:pml|hc|ml" \
  "points ML with LN k-means on the GPU at 10^5 (7,682 steps, 3-10 s on an H100 by its author) against the CPU's ML; 1M is in part 3" \
  '"$BIN/points_gpu_bench" --m "$POINTS_GPU_ML" --d 3 --blobs 1000 --algo ml --threads "$THREADS" --header'

# Part 2: the rest, in the order of the issue's list.
row 2 sums-1m 5 2 gpu_stages_bench \
  "cluster sums of 10^6 x 5 doubles: 0.22 s llvmpipe, x6 runs" \
  '"$BIN/gpu_stages_bench" sums --elements 1000000 --k "$LN_K" --values 5 --header'
row 2 pml-gpu-meshes 15 4 pml_gpu_bench \
  "bunny00 + armadillo, both pair rules, best of 3: 2 cores 0.35-2.8 s per run and device" \
  'for m in "$MESH_SMALL" "$MESH_MID"; do for p in all cheaper-half; do "$BIN/pml_gpu_bench" "$M/$m.off" --pairs "$p" --threads "$THREADS" --repeats 3 ${h---header}; h=; done; done'
row 2 pml-gpu-bb 90 40 pml_gpu_bench \
  "Alg. 5.7 (BB after each level), bunny00, armadillo, armadillo_1m, both pair rules; --quick (fandisk, bunny00) 22-52 s on llvmpipe; 1M: ~60 levels of BB sweeps on both" \
  'for m in "$MESH_SMALL" "$MESH_MID" "$MESH_1M"; do for p in all cheaper-half; do "$BIN/pml_gpu_bench" "$M/$m.off" --pairs "$p" --optimizer bb --threads "$THREADS" --repeats 1 ${h---header}; h=; done; done'
row 2 hc-gpu-meshes 90 8 hc_gpu_bench \
  "HC one collapse per step, bunny00, armadillo, armadillo_1m: 1M on 2 cores CPU 7.2 CPU-s, llvmpipe 346 s (832,000 steps, latency-bound: ~50 us a step there)" \
  'for m in "$MESH_SMALL" "$MESH_MID" "$MESH_1M"; do "$BIN/hc_gpu_bench" "$M/$m.off" --repeats 1 ${h---header}; h=; done'
row 2 ml-bb-gpu 60 25 pml_gpu_bench \
  "ML with BB (Alg. 5.6): fandisk whole hierarchy + bunny00's first 2,000 steps, each step O(faces); --quick (fandisk 2,000 steps) 20 s on llvmpipe" \
  'for r in "$ML_RUN_A" ${ML_RUN_B:+"$ML_RUN_B"}; do "$BIN/pml_gpu_bench" $r --algo ml --optimizer bb --threads "$THREADS" ${h---header}; h=; done'
row 2 points-pml-gpu-sizes 60 50 points_gpu_bench \
  "10^5 and 3*10^5 points, both pair rules, best of 3, and LN k-means inside the levels at 3*10^5 and 10^6; --quick (10^5 twice) 52 s on llvmpipe" \
  'for m in "$POINTS_MID" 100000; do for p in all cheaper-half; do "$BIN/points_gpu_bench" --m "$m" --d 3 --blobs 1000 --pairs "$p" --threads "$THREADS" --repeats 3 ${h---header}; h=; done; done; for m in "$POINTS_MID" "$POINTS_1M"; do "$BIN/points_gpu_bench" --m "$m" --d 3 --blobs 1000 --pairs cheaper-half --optimizer lnkmeans --threads "$THREADS" --repeats 1; done'
row 2 cpu-pml-ml-threads 60 3 pml_cpu_bench \
  "bench/pml_cpu_bench.sh, one round, bunny00 + armadillo on 1, 4 and 16 threads to k=1000 (2 cores: 1-3 s a run, 25 runs); armadillo_1m at 16 threads is in part 1" \
  'if [ "$MESH_1M" = armadillo_1m ]; then ms="bunny00 armadillo" tl="1 4 $THREADS"; else ms=fandisk tl="1 $THREADS"; fi; bash bench/pml_cpu_bench.sh "$BIN/.." --meshes "$ms" --rounds 1 --thread-list "$tl" --stop-at 1000'
row 2 points-hc-gpu-1m 70 15 "points_gpu_bench:pml|hc|ml" \
  "points HC on the GPU, 1M points: ~60,000 steps, latency-bound, 0.3-1 ms a step on an H100: 20-60 s; CPU HC 1-2 s (10^5 on llvmpipe: 150 s); may be cut at its cap: no partial row" \
  '"$BIN/points_gpu_bench" --m "$POINTS_GPU_HC" --d 3 --blobs 1000 --algo hc --threads "$THREADS" --header'
row 2 growth-patches 15 3 "gpu_stages_bench:growth MESH" \
  "growth at K = faces/124 on armadillo_1m (9.8 s on 2 loaded cores) and bunny00 at K = 1000 and 608 (0.9 s each)" \
  'for r in "$M/$GROWTH_1M.off --k $GROWTH_PATCHES" "$M/bunny00.off --k 1000" "$M/bunny00.off --k 608"; do "$BIN/gpu_stages_bench" growth $r --threads "$THREADS" ${h---header}; h=; done'

# Part 3: what fits neither call: the 1M points ML on the GPU, the curves, the context rows.
row 3 points-ml-gpu-1m 200 20 "points_gpu_bench:pml|hc|ml" \
  "the issue's row: points ML on the GPU at 1M (60,000 steps and LN k-means rounds, 60-180 s on an H100 by its author's guess) against the CPU's ML on 16 cores (10-40 s); may be cut at its cap: no partial row" \
  '"$BIN/points_gpu_bench" --m "$POINTS_GPU_ML_1M" --d 3 --blobs 1000 --algo ml --threads "$THREADS" --header'
row 3 points-ml-gpu-bounded 70 15 "points_gpu_bench:pml|hc|ml" \
  "points ML with bounded-drift 0.03 (ours) on the GPU at 3*10^5, against the CPU's" \
  '"$BIN/points_gpu_bench" --m "$POINTS_GPU_ML_MID" --d 3 --blobs 1000 --algo ml --bounded 0.03 --threads "$THREADS" --header'
row 3 points-ml-cpu-threads 85 12 points_bench \
  "the CPU's points ML at 1M on 2, 4 and 8 threads (~30, 18, 14 s) and with bounded-drift 0.03 on 16, hashes checked" \
  'for t in 2 4 8; do points_ml "$t" || exit 1; done; points_ml "$THREADS" --bounded 0.03'
row 3 pml-cpu-emlo 45 3 pml_cpu_bench \
  "for context: the CPU's PML as jobs run it (EMLO per level), three meshes; 1M ~30 s" \
  'for m in "$MESH_SMALL" "$MESH_MID" "$MESH_1M"; do "$BIN/pml_cpu_bench" "$M/$m.off" --algo pml --optimizer emlo --threads "$THREADS" ${h---header}; h=; done'
row 3 meshlets 45 10 meshlets_bench \
  "K = faces/124 (bench/peers/meshlets_bench.cc), 3 meshes x 5 repeats: 2 cores 0.05-0.42 s per peer and mesh, plus ML to K (--ml): armadillo_1m ~20 s on an idle core" \
  '"$BIN/meshlets_bench" "$M/$MESH_SMALL.off" "$M/$MESH_MID.off" "$M/$MESH_1M.off" --repeats 5 --threads "$THREADS" --sweeps 4,6,8 --ml --header'

# --- Selection --------------------------------------------------------------------------
selected=()
for i in "${!ids[@]}"; do
  if [ -n "$only" ]; then
    [[ "$only" == *",${ids[$i]},"* ]] || continue
  elif [ "$part" != all ] && [ "${parts[$i]}" != "$part" ]; then
    continue
  fi
  selected+=("$i")
done
estimate() { if [ "$quick" = 1 ]; then echo "${quick_est[$1]}"; else echo "${node_est[$1]}"; fi; }

# guard_fails I: prints why row I cannot run here (nothing when it can).
guard_fails() {
  local g="${guards[$1]}" name want
  case "$g" in
    -) ;;
    torch)
      env -u LD_LIBRARY_PATH python3 -c \
        "import torch, sys; sys.exit(0 if torch.cuda.is_available() else 1)" 2>/dev/null ||
        echo "torch with CUDA not available"
      ;;
    *)
      name="${g%%:*}" want=""
      [ "$name" != "$g" ] && want="${g#*:}"
      if [ ! -x "$BIN/$name" ]; then
        echo "no $BIN/$name"
      elif [ -n "$want" ] && ! grep -aqF -- "$want" "$BIN/$name"; then
        echo "no '$want' in $name"
      fi
      ;;
  esac
}

if [ "$check_guards" = 1 ]; then
  # Every row whose guard this build fails, torch aside (the device has it, here may not).
  missing=0
  for i in "${selected[@]}"; do
    [ "${guards[$i]}" = torch ] && continue
    why="$(guard_fails "$i")"
    [ -z "$why" ] && continue
    echo "gpu_node: row ${ids[$i]} (part ${parts[$i]}) would be skipped: $why"
    missing=$((missing + 1))
  done
  echo "gpu_node: $missing of ${#selected[@]} rows would be skipped by their guards with $BIN"
  exit 0
fi
if [ "$list_binaries" = 1 ]; then
  for g in "${guards[@]}"; do
    case "$g" in - | torch) ;; *) echo "bench/${g%%:*}" ;; esac
  done | sort -u
  echo gpu/mlclust-gpu-info
  exit 0
fi
if [ "$dry_run" = 1 ]; then
  total=0
  printf '%-4s %-26s %8s  %-20s %s\n' part row estimate guard basis
  for i in "${selected[@]}"; do
    e="$(estimate "$i")"
    total=$((total + e))
    printf '%-4s %-26s %7ss  %-20s %s\n' "${parts[$i]}" "${ids[$i]}" "$e" "${guards[$i]}" \
      "${bases[$i]}"
  done
  echo "total estimate: ${total}s for ${#selected[@]} rows ($([ "$quick" = 1 ] &&
    echo "--quick, 2 cores + llvmpipe" || echo "GPU node, $THREADS threads"))"
  exit 0
fi

# --- Running ----------------------------------------------------------------------------
if [ ! -x "$BIN/gpu_stages_bench" ]; then
  if [ "$build_dir" != build ]; then
    echo "gpu_node: $BIN/gpu_stages_bench missing" >&2
    exit 1
  fi
  CMAKE_CXX_COMPILER_LAUNCHER="${CMAKE_CXX_COMPILER_LAUNCHER:-}" bash scripts/build.sh
fi
host="$(uname -n)"  # hostname(1) may be missing on the device
if [ -z "$out_dir" ]; then
  out_dir=bench/results
  csv="$out_dir/gpu_node_${host%%.*}.csv"
  [ "$quick" = 1 ] && csv="$out_dir/gpu_node_quick.csv"
  status="${csv%.csv}_status.tsv"
else
  csv="$out_dir/gpu_node.csv" status="$out_dir/gpu_node_status.tsv"
fi
mkdir -p "$out_dir"
renderer="$("$build_dir/gpu/mlclust-gpu-info" --rows=8 --repeats=1 2>/dev/null |
  awk 'tolower($0) ~ /renderer/ && !n++ { print } END { if (!n) print "renderer: ?" }')"
echo "# run $(date -u +%FT%TZ) host=${host%%.*} cores=$(nproc) threads=$THREADS" \
  "part=$part quick=$quick budget=${budget:-none} $renderer" | tee -a "$csv"
[ -s "$status" ] || printf 'row\tpart\tstatus\tseconds\testimate\n' >>"$status"


slack="${GPU_NODE_ROW_SLACK:-60}"  # the cap's least slack over an estimate (tests: less)
started=$SECONDS
for i in "${selected[@]}"; do
  id="${ids[$i]}" e="$(estimate "$i")" limit=() cut="budget"
  why="$(guard_fails "$i")"
  if [ -z "$why" ] && [ -n "$budget" ]; then
    left=$((budget - (SECONDS - started)))
    if [ "$left" -lt "$e" ] || [ "$left" -le 0 ]; then
      why="budget (estimate ${e}s, ${left}s left)"
    else
      # A row gets at most 3x its estimate (at least a minute more), so that one row far
      # over its estimate leaves the later rows their turn.
      cap=$((3 * e > e + slack ? 3 * e : e + slack))
      if [ "$cap" -lt "$left" ]; then
        left="$cap" cut="3x its estimate"
      fi
      limit=(timeout -k 5 "$left")
    fi
  fi
  if [ -n "$why" ]; then
    echo "# row $id skipped: $why" | tee -a "$csv"
    printf '%s\t%s\tskipped: %s\t0\t%s\n' "$id" "${parts[$i]}" "$why" "$e" >>"$status"
    continue
  fi
  echo "# row $id part=${parts[$i]} estimate=${e}s $(date -u +%FT%TZ)" | tee -a "$csv"
  row_start=$SECONDS
  set +e
  "${limit[@]}" bash -c "set -o pipefail; ${commands[$i]}" | tee -a "$csv"
  rc=${PIPESTATUS[0]}
  set -e
  took=$((SECONDS - row_start))
  case "$rc" in
    0) state=ok ;;
    124 | 137) state="timeout: $cut" ;;
    *) state="failed: exit $rc" ;;
  esac
  [ "$rc" != 0 ] && echo "# row $id $state after ${took}s" | tee -a "$csv"
  printf '%s\t%s\t%s\t%s\t%s\n' "$id" "${parts[$i]}" "$state" "$took" "$e" >>"$status"
done
echo "wrote $csv and $status ($((SECONDS - started))s)"
