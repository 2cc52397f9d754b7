#!/usr/bin/env bash
# Reproduces every figure of BENCHMARKS.md's "Issue 3: mesh clustering core" and "Issue 4:
# multilevel engine" sections: builds our benchmarks (build-bench/), the CGAL peer
# (build-peers/) and the CLI (build-bench-srv/), fetches the meshes, runs everything, and
# writes CSVs, PNGs and the tables (bench/results/tables.md) to bench/results/.
#
#   bench/run_mesh_benchmarks.sh                     # everything, 3 interleaved repeats
#   bench/run_mesh_benchmarks.sh --only b,h          # some sections (a..i, see below)
#   bench/run_mesh_benchmarks.sh --repeats 1 --no-build --cli build-me/client/mlclust
#
#   a  EMLO (CVD, k=1000, l-neighbourhood and random initial clusters) vs CGAL VSA k=1000
#   b  our VSA vs CGAL VSA: L2,1 energy and time, k=50/200/1000, 4 meshes, 2 seedings;
#      and random seeding over seeds 1..6 on fandisk k=200 (energies only)
#   c  BB: time per sweep, threads 1 vs 2 (bunny00 k=1000, armadillo_1m k=10000)
#   d  "Table 3.1": l-neighbourhood init, MWCVD (w^A, w^V, w^M) + CVD EMLO time and energy
#   e  "Fig. 3.13": fandisk k=200 through the CLI (--algo emlo), rendered to PNG
#   f  the full ML hierarchy of bunny00 vs one CGAL VSA partition at k=1000
#   g  PML down to 2000 clusters then ML vs ML (bunny00, armadillo), and both without
#      the optimiser (HC, PML->2000 then HC) to show where the time goes
#   h  planar (L2,1) ML/HC/PML hierarchies (ML at k=200 vs CGAL's best seeding from b)
#   i  CVD ML/HC/PML/PML->ML hierarchies on 5 meshes: times, energies, curves, scaling
#
# Timing discipline (the machine is shared with other builds): every configuration runs
# --repeats times (default 3), each repeat running ours and the peer one after the other
# (interleaved), every tool invoked with one repeat of its own; the tables take the best
# repeat of each. Every row records the 1-minute load average when it ran (load1) and the
# process's wall-clock and CPU seconds (proc_wall_s, proc_cpu_s from /usr/bin/time), so a
# row whose process waited for a core (wall > 1.1 x CPU for a one-thread tool) shows it.
# bench/results/machine_mesh.txt records the machine, the commit and the load before and after.
#
# Output (bench/results/): emlo_vs_cgal_*, vsa_vs_cgal_*, vsa_seeds_vs_cgal_*, bb_sweep_threads,
# table3_1_mwcvd, fig3_13_cli.csv and fig313_*.png, ml_hierarchy_vs_cgal_*, pml_then_ml,
# planar_hierarchies, cvd_hierarchies.csv, curves/*.csv (energy per level, thinned to ~60
# levels per decade), curves_*.png, scaling.png, tables.md (bench/plot_mesh_tables.py), machine_mesh.txt.
# Needs: CMake, Ninja, g++, libcgal-dev and libcgal-demo (installed through
# scripts/bench-peers.sh / scripts/fetch-bench-meshes.sh when missing), /usr/bin/time,
# /usr/bin/python3 with numpy and matplotlib.
set -euo pipefail

repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$repo_root"
results="$repo_root/bench/results"
meshes_dir="$repo_root/data/bench"
bench_bin="$repo_root/build-bench/bench"
peer="$repo_root/build-peers/cgal_vsa"
cli="$repo_root/build-bench-srv/client/mlclust"
python=/usr/bin/python3
repeats=3
only="a,b,c,d,e,f,g,h,i"
build=1
cli_given=0
while [ $# -gt 0 ]; do
  case "$1" in
    --repeats) repeats="${2:?--repeats needs a value}"; shift 2 ;;
    --only) only="${2:?--only needs a list such as a,b}"; shift 2 ;;
    --no-build) build=0; shift ;;
    --cli) cli="$(realpath "${2:?--cli needs a path}")"; cli_given=1; shift 2 ;;
    -h | --help) sed -n '2,36p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "run_mesh_benchmarks: unknown argument '$1'" >&2; exit 2 ;;
  esac
done
want() { [[ ",$only," == *",$1,"* ]]; }
say() { echo "run_mesh_benchmarks: $*" >&2; }

# --- 1. Builds and meshes ------------------------------------------------------------------
if [ "$build" -eq 1 ]; then
  bash scripts/fetch-bench-meshes.sh >&2
  cmake -S . -B build-bench -G Ninja -DCMAKE_BUILD_TYPE=Release -DMLCLUST_WITH_GPU=OFF \
    -DMLCLUST_WITH_SERVER=OFF -DMLCLUST_BUILD_TESTS=OFF >/dev/null
  ninja -C build-bench mesh_bench vsa_bench ml_bench >&2
  if ! dpkg-query -W -f='${Status}' libcgal-dev 2>/dev/null | grep -q "install ok installed"; then
    # bench-peers.sh installs CGAL and builds the peer (and runs its own table: quick here).
    bash scripts/bench-peers.sh --repeats 1 --output "$(mktemp)" >&2
  fi
  cmake -S bench/peers -B build-peers -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
  ninja -C build-peers >&2
  if want e && [ "$cli_given" -eq 0 ]; then
    cmake -S . -B build-bench-srv -G Ninja -DCMAKE_BUILD_TYPE=Release -DMLCLUST_WITH_GPU=OFF \
      -DMLCLUST_WITH_SERVER=ON -DMLCLUST_BUILD_TESTS=OFF >/dev/null
    ninja -C build-bench-srv mlclust >&2
  fi
fi
mkdir -p "$results/curves"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

load1() { cut -d' ' -f1 /proc/loadavg; }

# machine_mesh.txt: what ran where; a run of every section starts it afresh, a run of some
# sections (--only) adds its own block.
[ "$only" = "a,b,c,d,e,f,g,h,i" ] && rm -f "$results/machine_mesh.txt"
{
  echo "--- sections $only"
  echo "date: $(date -u +%Y-%m-%dT%H:%M:%SZ)"
  echo "cpu: $(lscpu | sed -n 's/^Model name: *//p') x $(nproc) cores"
  echo "memory: $(free -g | awk '/^Mem:/ { print $2 " GiB" }')"
  echo "os: $(. /etc/os-release && echo "$PRETTY_NAME"), $(g++ --version | head -1)"
  echo "commit: $(git rev-parse --short HEAD) (working tree changes outside bench/:" \
    "$(git status --short -- . ':!bench' ':!BENCHMARKS.md' | awk '{ printf "%s ", $2 }'))"
  echo "repeats: $repeats$([ "$build" -eq 0 ] && echo ", --no-build: the binaries as last built")"
  echo "load before: $(cut -d' ' -f1-3 /proc/loadavg)"
} >>"$results/machine_mesh.txt"

# run FILE HEADER REP COMMAND...: runs COMMAND once under /usr/bin/time and appends its CSV
# rows (stdout; several for ml_bench) to FILE as "rep,load1,proc_wall_s,proc_cpu_s,ROW".
# FILE gets "rep,load1,proc_wall_s,proc_cpu_s,HEADER" first if it is new.
run() {
  local file="$1" header="$2" rep="$3"
  shift 3
  [ -f "$file" ] || echo "rep,load1,proc_wall_s,proc_cpu_s,$header" >"$file"
  local load
  load="$(load1)"
  if ! /usr/bin/time -f "%e %U %S" -o "$work/time" "$@" >"$work/out" 2>"$work/err"; then
    cat "$work/err" >&2
    say "failed: $*"
    exit 1
  fi
  local wall cpu suffix=""
  read -r wall cpu < <(awk '{ printf "%s %.2f\n", $1, $2 + $3 }' "$work/time")
  if [[ "$header" == *",optimiser_moves,evaluations" ]]; then
    # ml_bench's stderr: "run 0: 0.751 s, 75408 levels, 859281 triplets, 494869 optimiser
    # moves, 1639264 evaluations".
    suffix=",$(sed -n 's/.* \([0-9]*\) optimiser moves, \([0-9]*\) evaluations.*/\1,\2/p' \
      "$work/err" | head -1)"
  fi
  grep -v '^mesh,' "$work/out" | sed "s/^/$rep,$load,$wall,$cpu,/; s/\$/$suffix/" |
    tee -a "$file" >&2
}

readonly MB_HEADER="mesh,faces,k,energy,init,algo,threads,init_s,opt_s,total_s,initial_energy,final_energy,moves,iterations"
readonly VSA_HEADER="mesh,faces,k,seeding,iterations,seconds,energy"
readonly ML_HEADER="mesh,faces,algo,energy,optimizer,p_percent,pml_until,threads,seconds,levels,k,energy_at_k,optimiser_moves,evaluations"
readonly CGAL_HEADER="mesh,faces,k,k_obtained,seeding,iterations,seed_seconds,iterate_seconds,total_seconds,energy_l21,cgal_error"

mesh_bench() { run "$1" "$MB_HEADER" "$2" "$bench_bin/mesh_bench" "${@:3}" --repeats 1; }
vsa_bench() { run "$1" "$VSA_HEADER" "$2" "$bench_bin/vsa_bench" "${@:3}" --repeats 1; }
ml_bench() { run "$1" "$ML_HEADER" "$2" "$bench_bin/ml_bench" "${@:3}" --repeats 1; }
cgal_vsa() { run "$1" "$CGAL_HEADER" "$2" "$peer" "${@:3}" --repeats 1; }
# cgal_vsa_bunny CSV REP: CGAL VSA on bunny00 at k = 1000, random then hierarchical seeding.
cgal_vsa_bunny() {
  for seeding in random hierarchical; do
    cgal_vsa "$1" "$2" "$meshes_dir/bunny00.off" --k 1000 --seeding "$seeding"
  done
}

# thin_curve IN OUT: keeps every level with k <= 100 and the first level (largest k) of
# each 1/60 decade above, as clusters,energy.
thin_curve() {
  awk -F, 'NR == 1 { print; next }
           { k = $1; if (k <= 100) { print; next }
             b = int(60 * log(k) / log(10)); if (!(b in seen)) { seen[b] = 1; print } }' \
    "$1" >"$2"
}

fresh() { for f in "$@"; do rm -f "$results/$f"; done; }
M4=(fandisk bunny00 armadillo elephant)

# --- Issue 3 -----------------------------------------------------------------------------
if want a; then
  say "(a) EMLO k=1000 vs CGAL VSA k=1000 on bunny00"
  fresh emlo_vs_cgal_mesh_bench.csv emlo_vs_cgal_cgal_vsa.csv
  for rep in $(seq 1 "$repeats"); do
    for init in lneigh random; do
      mesh_bench "$results/emlo_vs_cgal_mesh_bench.csv" "$rep" "$meshes_dir/bunny00.off" --k 1000 \
        --energy cvd --init "$init" --algo emlo
    done
    cgal_vsa_bunny "$results/emlo_vs_cgal_cgal_vsa.csv" "$rep"
  done
fi

if want b; then
  say "(b) our VSA vs CGAL VSA"
  fresh vsa_vs_cgal_vsa_bench.csv vsa_vs_cgal_cgal_vsa.csv
  for mesh in "${M4[@]}"; do
    for k in 50 200 1000; do
      for seeding in hierarchical random; do
        for rep in $(seq 1 "$repeats"); do
          vsa_bench "$results/vsa_vs_cgal_vsa_bench.csv" "$rep" "$meshes_dir/$mesh.off" --k "$k" \
            --seeding "$seeding"
          cgal_vsa "$results/vsa_vs_cgal_cgal_vsa.csv" "$rep" "$meshes_dir/$mesh.off" --k "$k" \
            --seeding "$seeding"
        done
      done
    done
  done
fi

if want b; then
  # Random seeding is luck: the energy over seeds 1..6 (fandisk k=200: the one miss).
  fresh vsa_seeds_vs_cgal_vsa_bench.csv vsa_seeds_vs_cgal_cgal_vsa.csv
  for seed in 1 2 3 4 5 6; do
    vsa_bench "$results/vsa_seeds_vs_cgal_vsa_bench.csv" "$seed" "$meshes_dir/fandisk.off" --k 200 \
      --seeding random --seed "$seed"
    cgal_vsa "$results/vsa_seeds_vs_cgal_cgal_vsa.csv" "$seed" "$meshes_dir/fandisk.off" --k 200 \
      --seeding random --seed "$seed"
  done
fi

if want c; then
  say "(c) BB sweeps, threads 1 vs 2"
  fresh bb_sweep_threads.csv
  for spec in bunny00:1000 armadillo_1m:10000; do
    mesh="${spec%%:*}" k="${spec##*:}"
    for rep in $(seq 1 "$repeats"); do
      for threads in 1 2; do
        mesh_bench "$results/bb_sweep_threads.csv" "$rep" "$meshes_dir/$mesh.off" --k "$k" \
          --energy cvd --init lneigh --algo bb --threads "$threads"
      done
      mesh_bench "$results/bb_sweep_threads.csv" "$rep" "$meshes_dir/$mesh.off" --k "$k" \
        --energy cvd --init lneigh --algo emlo
    done
  done
fi

if want d; then
  say "(d) Table 3.1: l-neighbourhood + MWCVD EMLO"
  fresh table3_1_mwcvd.csv
  for spec in fandisk:1000 fandisk:100 bunny00:1000 armadillo:1000 elephant:1000 elephant:100; do
    mesh="${spec%%:*}" k="${spec##*:}"
    for rep in $(seq 1 "$repeats"); do
      for energy in mwcvd-area mwcvd-variance mwcvd-max cvd; do
        mesh_bench "$results/table3_1_mwcvd.csv" "$rep" "$meshes_dir/$mesh.off" --k "$k" \
          --energy "$energy" --init lneigh --algo emlo
      done
    done
  done
fi

if want e; then
  say "(e) Fig. 3.13: fandisk k=200 through the CLI ($cli)"
  fresh fig3_13_cli.csv
  if [ ! -x "$cli" ]; then
    say "no CLI at $cli: (e) skipped (build with -DMLCLUST_WITH_SERVER=ON or pass --cli)"
  else
    echo "energy,clusters,cli_seconds,energy_value,png_bytes" >"$results/fig3_13_cli.csv"
    for energy in cvd cvd-adaptive mwcvd-area mwcvd-variance mwcvd-max; do
      ply="$work/fandisk_$energy.ply" png="$results/fig313_fandisk_$energy.png"
      "$cli" mesh data/fandisk.off --algo emlo --energy "$energy" --clusters 200 \
        --ply "$ply" --quiet >"$work/cli.log" 2>&1
      cat "$work/cli.log" >&2
      # "...: 12946 faces, 2 levels, 4419 triplets in 0.015 s on cpu (embedded); level 1:
      # 200 clusters, energy 2.42e-06"
      seconds="$(sed -n 's/.* in \([0-9.]*\) s on .*/\1/p' "$work/cli.log" | tail -1)"
      value="$(sed -n 's/.*clusters, energy \([-0-9.e+]*\).*/\1/p' "$work/cli.log" | tail -1)"
      "$python" bench/plot_render.py "$ply" "$png" --dpi 80 --title "fandisk, $energy, k=200"
      echo "$energy,200,$seconds,$value,$(stat -c %s "$png")" >>"$results/fig3_13_cli.csv"
    done
  fi
fi

# --- Issue 4 -----------------------------------------------------------------------------
if want f; then
  say "(f) ML full hierarchy of bunny00 vs CGAL VSA k=1000"
  fresh ml_hierarchy_vs_cgal_ml_bench.csv ml_hierarchy_vs_cgal_cgal_vsa.csv
  for rep in $(seq 1 "$repeats"); do
    ml_bench "$results/ml_hierarchy_vs_cgal_ml_bench.csv" "$rep" "$meshes_dir/bunny00.off" --algo ml \
      --energy cvd --optimizer emlo --at 1000
    cgal_vsa_bunny "$results/ml_hierarchy_vs_cgal_cgal_vsa.csv" "$rep"
  done
fi

if want g; then
  say "(g) PML down to 2000 then ML vs ML"
  fresh pml_then_ml.csv
  for mesh in bunny00 armadillo; do
    for rep in $(seq 1 "$repeats"); do
      ml_bench "$results/pml_then_ml.csv" "$rep" "$meshes_dir/$mesh.off" --algo ml \
        --at 1000,200,50
      for threads in 0 1; do
        ml_bench "$results/pml_then_ml.csv" "$rep" "$meshes_dir/$mesh.off" --algo pml \
          --pml-until 2000 --threads "$threads" --at 1000,200,50
      done
      # Where the time goes: the same merges without the optimiser (HC; PML->2000 then HC).
      ml_bench "$results/pml_then_ml.csv" "$rep" "$meshes_dir/$mesh.off" --algo hc \
        --at 1000,200,50
      ml_bench "$results/pml_then_ml.csv" "$rep" "$meshes_dir/$mesh.off" --algo pml \
        --pml-until 2000 --optimizer none --at 1000,200,50
    done
  done
fi

# ml_runs FILE ENERGY MESH...: ML, HC, PML (to the end) and, for CVD, PML down to 2000 then
# ML, interleaved; the first repeat also writes each curve.
ml_runs() {
  local file="$1" energy="$2"
  shift 2
  for mesh in "$@"; do
    for rep in $(seq 1 "$repeats"); do
      local variants=(ml:0 hc:0 pml:0)
      [ "$energy" = cvd ] && variants+=(pml:2000)
      for variant in "${variants[@]}"; do
        local algo="${variant%%:*}" until="${variant##*:}" name curve=()
        name="$algo"
        [ "$until" -gt 0 ] && name="pml${until}ml"
        [ "$rep" -eq 1 ] && curve=(--curve "$work/curve.csv")
        ml_bench "$file" "$rep" "$meshes_dir/$mesh.off" --algo "$algo" --energy "$energy" \
          --pml-until "$until" --at 1000,200,50 "${curve[@]}"
        if [ "$rep" -eq 1 ]; then
          thin_curve "$work/curve.csv" "$results/curves/${mesh}_${energy}_${name}.csv"
        fi
      done
    done
  done
}

if want h; then
  say "(h) planar ML/HC/PML hierarchies"
  fresh planar_hierarchies.csv
  ml_runs "$results/planar_hierarchies.csv" planar "${M4[@]}"
fi

if want i; then
  say "(i) CVD ML/HC/PML hierarchies, 5 meshes"
  fresh cvd_hierarchies.csv
  ml_runs "$results/cvd_hierarchies.csv" cvd elephant fandisk armadillo bunny00 armadillo_1m
fi

echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)" >>"$results/machine_mesh.txt"

# --- Tables and plots --------------------------------------------------------------------
"$python" bench/plot_mesh_curves.py "$results"
"$python" bench/plot_mesh_tables.py "$results" >"$results/tables.md"
say "wrote $results/tables.md"
