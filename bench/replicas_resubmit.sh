#!/usr/bin/env bash
# A replica SIGKILLed in the middle of a job it accepted (client/replicas.h, issue 28): the
# time to the final result of one CLI job (ML on bunny00 subdivided twice, 1,206,528 faces,
# CPU) through two `mlclust serve` replicas, without a kill and with the accepting replica
# killed halfway through (once it has produced half the job's levels, KILL_AT=0.5, polled
# with `mlclust jobs` every 0.2 s; the time of the kill is printed, from the submission): the
# client submits the job again to the other replica, keeps the levels received, and its
# result must equal the no-kill run's (every level's cluster count and energy, and the
# labels at --clusters K), checked here.
#   bench/replicas_resubmit.sh [MLCLUST_BINARY] [BENCH_MESH_DIR] [RUNS]
#   KILL_AT=0.9 bench/replicas_resubmit.sh ...   # the kill once 90 % of the levels exist
# The mesh is made once in BENCH_MESH_DIR (default data/bench) from bunny00.off
# (scripts/fetch-bench-meshes.sh puts it there) with that script's subdivision (one copy).
set -euo pipefail
M=${1:-build/client/mlclust}; D=${2:-data/bench}; runs=${3:-1}; kill_at=${KILL_AT:-0.5}
mesh="$D/bunny00_x16.off"
if [ ! -s "$mesh" ]; then
  [ -s "$D/bunny00.off" ] || { echo "no $D/bunny00.off: run scripts/fetch-bench-meshes.sh" >&2; exit 1; }
  sed -n "/<<'PYTHON'/,/^PYTHON$/p" scripts/fetch-bench-meshes.sh | sed '1d;$d' > "$D/subdivide.py"
  python3 "$D/subdivide.py" "$D/bunny00.off" "$mesh.tmp" && mv "$mesh.tmp" "$mesh"
  rm -f "$D/subdivide.py"
fi
work=$(mktemp -d); pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; wait 2>/dev/null; rm -rf "$work"; }
trap cleanup EXIT
base=$((40000 + RANDOM % 10000))
serve() {  # serve PORT: a replica on 127.0.0.1:PORT, its pid in $served
  "$M" serve --listen "127.0.0.1:$1" --gpu off --list-all-jobs 2> "$work/serve$1.log" & served=$!; pids+=($served)
  for _ in $(seq 100); do grep -q serving "$work/serve$1.log" 2>/dev/null && return; sleep 0.1; done
  echo "replica $1 did not start" >&2; exit 1
}
job() {  # job NAME REPLICAS...: the CLI job, in order; its wall time in $NAME.s
  local name=$1; shift
  local start; start=$(date +%s.%N)
  "$M" mesh "$mesh" --server "$1" --spread in-order --algo ml --clusters 100 --device cpu \
    --labels "$work/$name.labels" --levels-csv "$work/$name.csv" > /dev/null 2> "$work/$name.err"
  echo "$(date +%s.%N) - $start" | bc > "$work/$name.s"
}
serve $base; a_pid=$served; serve $((base + 1))
a=127.0.0.1:$base b=127.0.0.1:$((base + 1))
echo "mesh: $mesh ($(sed -n 2p "$mesh" | awk '{print $2}') faces); runs: $runs"
for r in $(seq "$runs"); do
  job plain "$a,$b"
  plain=$(cat "$work/plain.s")
  # The kill run: A accepts the job (in order) and is SIGKILLed once KILL_AT of its levels
  # exist.
  levels=$(($(wc -l < "$work/plain.csv") - 1))
  at=$(echo "$levels * $kill_at / 1" | bc)
  start=$(date +%s.%N)
  job killed "$a,$b" &
  run=$!
  until "$M" jobs --server "$a" 2> /dev/null |
      awk -v at="$at" '$2 == "running" && $5 >= at { f = 1 } END { exit !f }'; do
    kill -0 "$run" 2> /dev/null || break
    sleep 0.2
  done
  half=$(echo "$(date +%s.%N) - $start" | bc)
  kill -KILL "$a_pid"
  wait "$run" || { echo "the killed run failed: $(cat "$work/killed.err")" >&2; exit 1; }
  cmp -s "$work/plain.csv" "$work/killed.csv" || { echo "levels differ" >&2; exit 1; }
  cmp -s "$work/plain.labels" "$work/killed.labels" || { echo "labels differ" >&2; exit 1; }
  kept=$(sed -n 's/.*keeping the \([0-9]*\) levels received.*/\1/p' "$work/killed.err")
  printf "run %d: no kill %.2f s; killed at %.2f s: final result at %.2f s (%.2fx), %s of %d levels kept from A; results identical\n" \
    "$r" "$plain" "$half" "$(cat "$work/killed.s")" "$(echo "$(cat "$work/killed.s") / $plain" | bc -l)" \
    "${kept:-none}" "$levels"
  serve $base; a_pid=$served  # A again for the next run
done
