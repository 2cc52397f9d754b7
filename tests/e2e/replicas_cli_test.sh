#!/usr/bin/env bash
# Three `mlclust serve` on loopback ports behind one --server list; one (B) holds a detached
# job, is frozen (SIGSTOP) while a batch of jobs is submitted and then killed (SIGKILL)
# mid-batch: every job of the batch still finishes with the labels of a solo run (a job
# that was waiting on B is retried elsewhere, as B never accepted it), and the detached
# job on B reports clearly that its replica is gone. A fourth replica (D) SIGKILLed in the
# middle of a job it accepted, its levels streaming, loses no job: the client submits it
# again to the next replica (a line on stderr says so), keeps the levels received, and its
# result equals a solo run's, level by level (every level's cluster count and energy, and
# the labels at K); with --resubmit 0 the job fails instead, saying so.
#   replicas_cli_test.sh MLCLUST_BINARY DATA_DIR
set -euo pipefail
mlclust=$1
data=$2
work=$(mktemp -d)
pids=()
cleanup() {
  for pid in "${pids[@]}"; do
    kill -CONT "$pid" 2>/dev/null || true
    kill "$pid" 2>/dev/null && wait "$pid" 2>/dev/null || true
  done
  rm -rf "$work"
}
trap cleanup EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

base=$((20000 + RANDOM % 20000))
addresses=()
for i in 0 1 2; do
  port=$((base + i))
  "$mlclust" serve --listen "127.0.0.1:$port" --gpu off --list-all-jobs 2> "$work/server$i.log" &
  pids+=($!)
  addresses+=("127.0.0.1:$port")
done
for i in 0 1 2; do
  for _ in $(seq 100); do
    grep -q "serving" "$work/server$i.log" 2>/dev/null && break
    sleep 0.1
  done
  grep -q "serving" "$work/server$i.log" || fail "server $i did not start: $(cat "$work/server$i.log")"
done
a=${addresses[0]} b=${addresses[1]} c=${addresses[2]}
b_pid=${pids[1]}
all="$a,$b,$c"

# Solo reference on A.
"$mlclust" mesh "$data/fandisk.off" --server "$a" --algo ml --clusters 50 \
  --labels "$work/solo.labels" --quiet > /dev/null || fail "solo run"

# A detached job on B (in order: B first); its id names B.
"$mlclust" mesh "$data/fandisk.off" --server "$b,$a,$c" --spread in-order --algo ml --detach \
  > "$work/detach.out" || fail "detach"
id=$(tail -n 1 "$work/detach.out")
[ "${id%/*}" = "$b" ] || fail "the detached id '$id' does not name replica $b"
"$mlclust" watch "$id" --quiet > "$work/watch_before.out" || fail "watch before the kill"
grep -q "^$id: 12946 elements" "$work/watch_before.out" || fail "watch: $(cat "$work/watch_before.out")"

# B freezes; a batch starts: six jobs spread over the replicas (least loaded first; B does
# not answer GetStats, so it comes last) and one that tries B first (in order) and waits on
# it; then B is killed. Every job finishes.
kill -STOP "$b_pid"
batch=()
for j in 0 1 2 3 4 5; do
  "$mlclust" mesh "$data/fandisk.off" --server "$all" --algo ml --clusters 50 \
    --labels "$work/batch$j.labels" --quiet > "$work/batch$j.out" 2> "$work/batch$j.err" &
  batch+=($!)
done
"$mlclust" mesh "$data/fandisk.off" --server "$b,$a,$c" --spread in-order --algo ml \
  --clusters 50 --labels "$work/batch6.labels" > "$work/batch6.out" 2> "$work/batch6.err" &
batch+=($!)
sleep 1
kill -KILL "$b_pid"
for j in "${!batch[@]}"; do
  wait "${batch[$j]}" || fail "batch job $j failed: $(cat "$work/batch$j.err")"
  cmp -s "$work/solo.labels" "$work/batch$j.labels" || fail "batch job $j: labels differ from solo"
done
grep -q "replica $b did not accept the job" "$work/batch6.err" ||
  fail "the job that waited on B does not say it was retried: $(cat "$work/batch6.err")"

# The detached job on B: its replica is gone, said clearly.
set +e
"$mlclust" watch "$id" --quiet > /dev/null 2> "$work/watch_after.err"
rc=$?
"$mlclust" cancel "$id" > /dev/null 2> "$work/cancel_after.err"
cancel_rc=$?
"$mlclust" jobs --server "$all" > "$work/jobs.out" 2> "$work/jobs.err"
jobs_rc=$?
"$mlclust" watch job-000001 --server "$all" > /dev/null 2> "$work/noreplica.err"
noreplica_rc=$?
set -e
[ "$rc" = 1 ] || fail "watch on the killed replica: exit $rc"
grep -q "replica $b, which holds job ${id#*/}, does not answer" "$work/watch_after.err" ||
  fail "watch: $(cat "$work/watch_after.err")"
[ "$cancel_rc" = 1 ] || fail "cancel on the killed replica: exit $cancel_rc"
grep -q "does not answer" "$work/cancel_after.err" || fail "cancel: $(cat "$work/cancel_after.err")"
[ "$jobs_rc" = 0 ] || fail "jobs over the replicas: exit $jobs_rc"
grep -q "replica $b" "$work/jobs.err" || fail "jobs does not name the gone replica"
grep -q "^$a/job-" "$work/jobs.out" || fail "jobs: $(cat "$work/jobs.out")"
[ "$noreplica_rc" = 2 ] || fail "an id without its replica and several servers: exit $noreplica_rc"
grep -q "HOST:PORT/JOBID" "$work/noreplica.err" || fail "$(cat "$work/noreplica.err")"

# A replica that dies AFTER accepting a job, in the middle of its levels: the job is
# submitted again to the next replica (in order: A), the result that of a solo run.
awk 'BEGIN { n = 250; print "OFF"; print (n + 1) * (n + 1), 2 * n * n, 0;
  for (j = 0; j <= n; ++j) for (i = 0; i <= n; ++i) print i, j, 0.3 * sin(i * 0.7) * cos(j * 0.4);
  for (j = 0; j < n; ++j) for (i = 0; i < n; ++i) { a = j * (n + 1) + i; b = a + 1;
    c = a + n + 1; d = c + 1; print 3, a, b, d; print 3, a, d, c } }' > "$work/grid.off"
"$mlclust" mesh "$work/grid.off" --server "$a" --algo ml --clusters 50 --labels "$work/grid_solo.labels" \
  --levels-csv "$work/grid_solo.csv" --quiet > /dev/null || fail "solo run of the grid"
start_replica() {  # start_replica PORT LOG: its pid in $replica_pid, once it serves
  "$mlclust" serve --listen "127.0.0.1:$1" --gpu off --list-all-jobs 2> "$2" &
  replica_pid=$!
  pids+=($replica_pid)
  for _ in $(seq 100); do
    grep -q "serving" "$2" 2>/dev/null && break
    sleep 0.1
  done
}
# kill_when_streaming ADDRESS PID: SIGKILL once the job there is running with levels sent.
kill_when_streaming() {
  for _ in $(seq 600); do
    "$mlclust" jobs --server "$1" 2> /dev/null |
      awk '$2 == "running" && $5 > 1 { found = 1 } END { exit !found }' && break
    sleep 0.05
  done
  kill -KILL "$2"
}
port=$((base + 3))
d="127.0.0.1:$port"
start_replica "$port" "$work/server3.log"
"$mlclust" mesh "$work/grid.off" --server "$d,$a,$c" --spread in-order --algo ml --clusters 50 \
  --labels "$work/grid_resubmitted.labels" --levels-csv "$work/grid_resubmitted.csv" \
  > /dev/null 2> "$work/resubmitted.err" &
run_pid=$!
kill_when_streaming "$d" "$replica_pid"
wait "$run_pid" || fail "a job whose replica died mid-job: $(cat "$work/resubmitted.err")"
grep -q "replica $d accepted the job and then became unreachable (.*); submitting it again to the next replica (try 1 of 2), keeping the [0-9]* levels received" \
  "$work/resubmitted.err" || fail "no resubmission line: $(cat "$work/resubmitted.err")"
kept=$(sed -n 's/.*keeping the \([0-9]*\) levels received.*/\1/p' "$work/resubmitted.err")
[ "$kept" -gt 1 ] || fail "the kill came before any level was received ($kept)"
cmp -s "$work/grid_solo.csv" "$work/grid_resubmitted.csv" ||
  fail "the resubmitted job's levels differ from a solo run's"
cmp -s "$work/grid_solo.labels" "$work/grid_resubmitted.labels" ||
  fail "the resubmitted job's labels differ from a solo run's"
"$mlclust" jobs --server "$a" > "$work/jobs_a.out" 2> /dev/null
# The solo run and the resubmitted job.
[ "$(grep -c "succeeded.*grid.off" "$work/jobs_a.out")" = 2 ] ||
  fail "A did not run the resubmitted job: $(cat "$work/jobs_a.out")"

# --resubmit 0: the job fails, saying that its replica was lost and the limit.
port=$((base + 4))
e="127.0.0.1:$port"
start_replica "$port" "$work/server4.log"
set +e
"$mlclust" mesh "$work/grid.off" --server "$e,$a,$c" --spread in-order --algo ml --resubmit 0 \
  --quiet > /dev/null 2> "$work/accepted.err" &
run_pid=$!
kill_when_streaming "$e" "$replica_pid"
wait "$run_pid"
accepted_rc=$?
set -e
[ "$accepted_rc" = 1 ] || fail "--resubmit 0 and a replica that died mid-job: exit $accepted_rc"
grep -q "replica $e accepted the job and then became unreachable .*the limit (--resubmit 0)" \
  "$work/accepted.err" || fail "$(cat "$work/accepted.err")"
echo "replicas_cli_test: OK"
