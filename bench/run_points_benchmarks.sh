#!/usr/bin/env bash
# Reproduces the figures of BENCHMARKS.md's "Issue 5: point clustering" section: builds our
# benchmarks (build-bench/, unless --bin DIR), writes the synthetic data sets with
# bench/points_data.py (data/bench/points/, git-ignored), runs ours and the peers
# (bench/peers/points_peers.py under Debian's /usr/bin/python3: scikit-learn, fastcluster,
# faiss) one after the other, and writes CSVs, JSON lines and PNGs to bench/results/.
#
#   bench/run_points_benchmarks.sh                  # everything (~20 minutes on 2 cores)
#   bench/run_points_benchmarks.sh --only a,e       # some sections
#   bench/run_points_benchmarks.sh --bin build-me/bench --only f
#
#   a  LN k-means and Lloyd (ours) vs scikit-learn KMeans(lloyd) and faiss on 1M 3-D
#      points, k = 1000, k-means++ seeds (ours greedy k-means++, sklearn's kmeans_plusplus)
#   b  the ML / PML / HC hierarchies of 100k 3-D points vs fastcluster's Ward
#      (linkage_vector), energies at k = 10, 50, 100 (three data sets, seeds 1-3)
#   c  the hierarchies of 1M 3-D points (Ward's O(n^2) is out of reach there)
#   d  the true-K experiment (Fig. 6.15): K = 10..250 blobs of 500 points, 10 sets per K,
#      BIC of the ML hierarchy; Ward + the same BIC on 3 sets at K = 200 and 250
#   e  Fig. 6.11: time vs k at m = 1M (LN k-means, Lloyd)
#   f  Fig. 6.12: time vs m at k = 1000 (LN k-means, Lloyd) and of the full hierarchies
#   g  Fig. 6.13: time per ML step vs d = 2..64 (m = 20,000, 50 blobs)
#   h  a real point cloud: the 416,002 vertices of armadillo_1m (scripts/fetch-bench-meshes.sh)
#      as 3-D points: the hierarchies, LN k-means and Lloyd at k = 1000 vs scikit-learn
#   i  ML for points (BENCHMARKS "ML for points: per-point margins"): the whole ML hierarchy
#      of 100k, 300k and 1M points (1,000 blobs) with its fingerprint and CPU seconds, and
#      optimise_rounds 8/4/2/1 at 300k with every level's energy (points_ml_rounds_r*.csv)
#
# Every row of ours carries the 1-minute load average when it ran (load1). Output
# (bench/results/): points_*.csv / *.jsonl, points_true_k.png, points_fig6_1{1,2,3}.png
# (bench/plot_points.py), machine_points.txt (appended to: one record per run).
set -euo pipefail

repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$repo_root"
results="$repo_root/bench/results"
data="$repo_root/data/bench/points"
bin="$repo_root/build-bench/bench"
python=/usr/bin/python3
peers="$python $repo_root/bench/peers/points_peers.py"
only="a,b,c,d,e,f,g,h,i"
build=1
while [ $# -gt 0 ]; do
  case "$1" in
    --only) only="${2:?--only needs a list such as a,b}"; shift 2 ;;
    --bin) bin="$(realpath "${2:?--bin needs a directory}")"; build=0; shift 2 ;;
    -h | --help) sed -n '2,30p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "run_points_benchmarks: unknown argument '$1'" >&2; exit 2 ;;
  esac
done
wants() { [[ ",$only," == *",$1,"* ]]; }
load1() { cut -d' ' -f1 /proc/loadavg; }

for module in numpy sklearn fastcluster faiss matplotlib; do
  "$python" -c "import $module" 2>/dev/null ||
    { echo "run_points_benchmarks: $python lacks $module: run scripts/install-deps.sh --bench" >&2; exit 1; }
done
if [ "$build" = 1 ]; then
  cmake -S . -B build-bench -G Ninja -DCMAKE_BUILD_TYPE=Release -DMLCLUST_WITH_GPU=OFF \
    -DMLCLUST_WITH_SERVER=OFF > /dev/null
  cmake --build build-bench --target points_bench truek_bench > /dev/null
fi
mkdir -p "$results" "$data"
{
  echo "--- sections $only"
  echo "date: $(date -u +%FT%TZ)"
  echo "commit: $(git rev-parse --short HEAD)"
  echo "cpu: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ //') x $(nproc)"
  echo "load before: $(cat /proc/loadavg)"
} >> "$results/machine_points.txt"

blobs() {  # m d blobs seed file
  [ -f "$5" ] || "$python" bench/points_data.py --m "$1" --d "$2" --blobs "$3" --seed "$4" --out "$5"
}
ours() {  # csv-file, then points_bench arguments
  local out="$1"; shift
  local row
  row="$("$bin/points_bench" "$@" 2>/dev/null)"
  echo "$row,$(load1)" >> "$out"
  echo "  $row"
}
header="algo,m,d,blobs,k,grid,threads,seconds,init_seconds,steps,energy,start_clusters,load1"

if wants a; then
  echo "a: LN k-means vs scikit-learn and faiss, 1M x 3, k = 1000"
  f="$data/blobs_1m_d3_k1000.npy"
  blobs 1000000 3 1000 1 "$f"
  echo "$header" > "$results/points_lnkmeans_1m_ours.csv"
  for algo in lnkmeans kmeans; do ours "$results/points_lnkmeans_1m_ours.csv" --algo "$algo" --input "$f" --k 1000 --seed 1; done
  "$bin/points_bench" --algo lnkmeans --input "$f" --k 1000 --seed 1 2>&1 >/dev/null |
    tee "$results/points_lnkmeans_1m_lnkmeans_iterations.txt"
  $peers sklearn-kmeans "$f" --k 1000 --seed 1 | tee "$results/points_lnkmeans_1m_peers.jsonl"
  $peers faiss-kmeans "$f" --k 1000 --iterations 25 --seed 1 | tee -a "$results/points_lnkmeans_1m_peers.jsonl"
fi

if wants b; then
  echo "b: hierarchies of 100k x 3 vs fastcluster Ward"
  echo "$header" > "$results/points_ml_vs_ward_ours.csv"
  : > "$results/points_ml_vs_ward_ward.jsonl"
  for seed in 1 2 3; do
    f="$data/blobs_100k_d3_k100_s$seed.npy"
    blobs 100000 3 100 "$seed" "$f"
    for algo in ml pml hc; do
      for k in 10 50 100; do ours "$results/points_ml_vs_ward_ours.csv" --algo "$algo" --input "$f" --k "$k"; done
    done
    "$bin/points_bench" --algo ml --input "$f" --k 1 --curve "$results/points_ml_vs_ward_ml_curve_s$seed.csv" > /dev/null
    "$bin/points_bench" --algo pml --input "$f" --k 1 --curve "$results/points_ml_vs_ward_pml_curve_s$seed.csv" > /dev/null
    $peers fastcluster-ward "$f" --ks 10,20,30,40,50,60,80,100 | tee -a "$results/points_ml_vs_ward_ward.jsonl"
  done
fi

if wants c; then
  echo "c: hierarchies of 1M x 3"
  f="$data/blobs_1m_d3_k1000.npy"
  blobs 1000000 3 1000 1 "$f"
  echo "$header" > "$results/points_ml_1m.csv"
  for algo in ml pml hc; do ours "$results/points_ml_1m.csv" --algo "$algo" --input "$f" --k 1000; done
fi

if wants d; then
  echo "d: true-K experiment (Fig. 6.15)"
  mkdir -p "$data/truek"
  "$bin/truek_bench" --sets 10 --write-npy "$data/truek" | tee "$results/points_true_k_ml.csv"
  : > "$results/points_true_k_ward.jsonl"
  for K in 200 250; do
    for s in 0 1 2; do
      $peers ward-bic "$data/truek/truek_K${K}_s$s.npy" --max-k 320 | tee -a "$results/points_true_k_ward.jsonl"
    done
  done
fi

if wants e; then
  echo "e: time vs k (Fig. 6.11), m = 1M"
  f="$data/blobs_1m_d3_k1000.npy"
  blobs 1000000 3 1000 1 "$f"
  echo "$header" > "$results/points_time_vs_k.csv"
  for k in 100 250 500 1000 2000; do
    for algo in lnkmeans kmeans; do ours "$results/points_time_vs_k.csv" --algo "$algo" --input "$f" --k "$k"; done
  done
fi

if wants f; then
  echo "f: time vs m (Fig. 6.12), k = 1000"
  echo "$header" > "$results/points_time_vs_m.csv"
  for m in 100000 200000 500000 1000000 2000000; do
    f="$data/blobs_m${m}_d3_k1000.npy"
    blobs "$m" 3 1000 1 "$f"
    for algo in lnkmeans kmeans; do ours "$results/points_time_vs_m.csv" --algo "$algo" --input "$f" --k 1000; done
    if [ "$m" -le 1000000 ]; then
      for algo in ml pml hc; do ours "$results/points_time_vs_m.csv" --algo "$algo" --input "$f" --k 1000; done
    fi
    [ "$m" -le 1000000 ] || rm -f "$f"
  done
fi

if wants g; then
  echo "g: time per ML step vs d (Fig. 6.13), m = 20,000, 50 blobs"
  echo "$header" > "$results/points_time_vs_d.csv"
  for d in 2 3 4 8 16 32 64; do
    f="$data/blobs_20k_d${d}_k50.npy"
    blobs 20000 "$d" 50 1 "$f"
    for algo in ml hc; do ours "$results/points_time_vs_d.csv" --algo "$algo" --input "$f" --k 50; done
  done
fi

if wants h; then
  echo "h: a real point cloud, armadillo_1m's vertices"
  [ -f data/bench/armadillo_1m.off ] || bash scripts/fetch-bench-meshes.sh
  f="$data/armadillo_1m_vertices.npy"
  [ -f "$f" ] || "$python" bench/points_data.py --from-off data/bench/armadillo_1m.off --out "$f"
  echo "$header" > "$results/points_armadillo_ours.csv"
  for algo in ml pml hc; do ours "$results/points_armadillo_ours.csv" --algo "$algo" --input "$f" --k 1000; done
  for algo in lnkmeans kmeans; do ours "$results/points_armadillo_ours.csv" --algo "$algo" --input "$f" --k 1000 --seed 1; done
  $peers sklearn-kmeans "$f" --k 1000 --seed 1 | tee "$results/points_armadillo_peers.jsonl"
fi

if wants i; then
  echo "i: ML for points, whole hierarchy, fingerprints and CPU time; optimise_rounds"
  out="$results/points_ml_margins.txt"
  : > "$out"
  timed() {  # label, then points_bench arguments: the row, the fingerprint, CPU seconds
    local label="$1"; shift
    local load; load="$(load1)"
    /usr/bin/time -f "user=%U wall=%e" "$bin/points_bench" "$@" > "$out.row" 2> "$out.err"
    echo "$label load1=$load $(cat "$out.row") $(grep -h -e fingerprint -e user= "$out.err" | tr '\n' ' ')" |
      tee -a "$out"
  }
  for m in 100000 300000 1000000; do
    for t in 2 1; do
      timed "ml m=$m threads=$t" --algo ml --m "$m" --blobs 1000 --threads "$t" --fingerprint 1
    done
  done
  for r in 8 4 2 1; do
    timed "ml m=300000 rounds=$r" --algo ml --m 300000 --blobs 1000 --rounds "$r" \
      --curve "$results/points_ml_rounds_r$r.csv"
  done
  rm -f "$out.row" "$out.err"
fi

echo "load after: $(cat /proc/loadavg)" >> "$results/machine_points.txt"
"$python" bench/plot_points.py "$results"
