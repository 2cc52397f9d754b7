#!/usr/bin/env bash
# Three `mlclust serve` on loopback ports behind one --server list; one (B) holds a detached
# job, is frozen (SIGSTOP) while a batch of jobs is submitted and then killed (SIGKILL)
# mid-batch: every job of the batch still finishes with the labels of a solo run (a job
# that was waiting on B is retried elsewhere, as B never accepted it), and the detached
# job on B reports clearly that its replica is gone. A fourth replica killed after it
# accepted a job fails that job with a message saying so; it is not submitted again.
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

# A replica that dies AFTER accepting a job: the job fails with a message saying so, and is
# not submitted to another replica (A and C list no job of that label).
awk 'BEGIN { n = 250; print "OFF"; print (n + 1) * (n + 1), 2 * n * n, 0;
  for (j = 0; j <= n; ++j) for (i = 0; i <= n; ++i) print i, j, 0.3 * sin(i * 0.7) * cos(j * 0.4);
  for (j = 0; j < n; ++j) for (i = 0; i < n; ++i) { a = j * (n + 1) + i; b = a + 1;
    c = a + n + 1; d = c + 1; print 3, a, b, d; print 3, a, d, c } }' > "$work/grid.off"
port=$((base + 3))
"$mlclust" serve --listen "127.0.0.1:$port" --gpu off --list-all-jobs 2> "$work/server3.log" &
d_pid=$!
pids+=($d_pid)
d="127.0.0.1:$port"
for _ in $(seq 100); do
  grep -q "serving" "$work/server3.log" 2>/dev/null && break
  sleep 0.1
done
"$mlclust" mesh "$work/grid.off" --server "$d,$a,$c" --spread in-order --algo ml   --quiet > /dev/null 2> "$work/accepted.err" &
run_pid=$!
for _ in $(seq 200); do
  "$mlclust" jobs --server "$d" 2> /dev/null | grep -q "running" && break
  sleep 0.05
done
kill -KILL "$d_pid"
set +e
wait "$run_pid"
accepted_rc=$?
set -e
[ "$accepted_rc" = 1 ] || fail "a job whose replica died after accepting it: exit $accepted_rc"
grep -q "replica $d accepted the job and then became unreachable; the job is not submitted again" \
  "$work/accepted.err" || fail "$(cat "$work/accepted.err")"
if "$mlclust" jobs --server "$a,$c" 2> /dev/null | grep -q "grid.off"; then
  fail "the accepted job was submitted again"
fi
echo "replicas_cli_test: OK"
