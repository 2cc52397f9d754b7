#!/usr/bin/env bash
# Runs the benchmark peers: CGAL's Variational Shape Approximation (bench/peers/cgal_vsa.cc)
# on fandisk, bunny00, armadillo and elephant at k = 50, 200, 1000 with random and
# hierarchical seeding, writes bench/results/cgal_vsa.csv and prints a table.
#
# Installs libcgal-dev if it is missing (apt-get; root or sudo), fetches the meshes with
# scripts/fetch-bench-meshes.sh --no-1m, and builds bench/peers into build-peers/ (a CMake
# project of its own: the product and CI do not need CGAL). Idempotent.
#
#   scripts/bench-peers.sh                      # everything, best of 3, 30 iterations
#   scripts/bench-peers.sh --repeats 1 --iterations 20 --output /tmp/vsa.csv
#
# CSV columns: mesh,faces,k,seeding,iterations,seed_seconds,iterate_seconds,total_seconds,
# energy_l21 (seconds: best of the repeats, one thread; energy: our L2,1 energy of CGAL's
# final labels; see bench/peers/cgal_vsa.cc).
set -euo pipefail

readonly PACKAGE=libcgal-dev
readonly MESHES=(fandisk bunny00 armadillo elephant)
readonly KS=(50 200 1000)
readonly SEEDINGS=(random hierarchical)

repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build_dir="$repo_root/build-peers"
output="$repo_root/bench/results/cgal_vsa.csv"
repeats=3
iterations=30
while [ $# -gt 0 ]; do
  case "$1" in
    --repeats) repeats="${2:?--repeats needs a value}"; shift 2 ;;
    --iterations) iterations="${2:?--iterations needs a value}"; shift 2 ;;
    --output) output="${2:?--output needs a value}"; shift 2 ;;
    -h | --help) sed -n '2,17p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "bench-peers: unknown argument '$1'" >&2; exit 2 ;;
  esac
done

# --- 1. CGAL ---------------------------------------------------------------------------
bash "$repo_root/scripts/apt-ensure.sh" bench-peers "$PACKAGE" cmake ninja-build g++

# --- 2. The meshes (the peers do not use the million-face armadillo) -------------------
bash "$repo_root/scripts/fetch-bench-meshes.sh" --no-1m

# --- 3. The peers ----------------------------------------------------------------------
cmake -S "$repo_root/bench/peers" -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
ninja -C "$build_dir"

# --- 4. The runs -----------------------------------------------------------------------
mkdir -p "$(dirname "$output")"
raw="$(mktemp)"
csv="$(mktemp)"
log="$(mktemp)"
trap 'rm -f "$raw" "$csv" "$log"' EXIT
attempts=3
disturbed=()
# Other work on the machine skews the timings: the load averages are printed before and after.
echo "bench-peers: cgal_vsa, $iterations iterations, best of $repeats (on $(nproc) cores)"
echo "bench-peers: load average before: $(cut -d' ' -f1-3 /proc/loadavg)"
for mesh in "${MESHES[@]}"; do
  for k in "${KS[@]}"; do
    for seeding in "${SEEDINGS[@]}"; do
      # cgal_vsa warns when its best repeat waited for a core (wall-clock > 1.1 x CPU time):
      # such a configuration is run again, up to $attempts times in all.
      for attempt in $(seq 1 "$attempts"); do
        if ! line="$("$build_dir/cgal_vsa" "$repo_root/data/bench/$mesh.off" --k "$k" \
          --seeding "$seeding" --iterations "$iterations" --repeats "$repeats" 2>"$log")"; then
          cat "$log" >&2
          echo "bench-peers: cgal_vsa failed on $mesh k=$k $seeding" >&2
          exit 1
        fi
        if ! grep -q "disturbed timing" "$log"; then break; fi
        echo "  $mesh k=$k $seeding: disturbed by other load (attempt $attempt/$attempts)" >&2
      done
      if grep -q "disturbed timing" "$log"; then disturbed+=("$mesh k=$k $seeding"); fi
      grep "warning" "$log" | grep -v "disturbed timing" >&2 || true
      echo "  $line" >&2
      echo "$line" >>"$raw"
    done
  done
done

# cgal_vsa prints mesh,faces,k,k_obtained,seeding,iterations,seed_seconds,iterate_seconds,
# total_seconds,energy_l21,cgal_error.
echo "mesh,faces,k,seeding,iterations,seed_seconds,iterate_seconds,total_seconds,energy_l21" >"$csv"
awk -F, -v OFS=, '{ print $1, $2, $3, $5, $6, $7, $8, $9, $10 }' "$raw" >>"$csv"
mv "$csv" "$output"
echo "bench-peers: load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
echo "bench-peers: wrote $output"

awk -F, '{ if ($4 != $3) printf "bench-peers: warning: %s k=%s %s gave %s proxies\n", $1, $3, $5, $4 }' \
  "$raw" >&2
printf '\n%-10s %7s %5s %-12s %5s %9s %9s %9s %12s\n' mesh faces k seeding k_got \
  seed_s iter_s total_s energy_l21
awk -F, '{ printf "%-10s %7d %5d %-12s %5d %9.3f %9.3f %9.3f %12.6g\n",
                  $1, $2, $3, $5, $4, $7, $8, $9, $10 }' "$raw"
if [ "${#disturbed[@]}" -gt 0 ]; then
  echo "bench-peers: warning: timings disturbed by other load in: ${disturbed[*]}" >&2
fi
