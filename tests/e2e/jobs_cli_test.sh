#!/usr/bin/env bash
# Detached jobs from the command line against a real `mlclust serve`: --detach prints the
# job id (last line); `watch` writes the same outputs as an attached run, from any level;
# `jobs` lists them; `cancel` ends a queued job; --deadline ends a call with a clear message;
# a dropped or unknown job is NOT_FOUND with a reason.
#   jobs_cli_test.sh MLCLUST_BINARY DATA_DIR
source "$(dirname "$0")/cli_lib.sh" "$@"

port=$((20000 + RANDOM % 20000))
start_server "$work/server.log" --listen "127.0.0.1:$port" --retention-seconds 3 --gpu off --list-all-jobs
server="127.0.0.1:$port"
# A mesh big enough that ML runs for seconds: a 300 x 300 grid (180,000 faces), slightly wavy.
awk 'BEGIN { n = 300; print "OFF"; print (n + 1) * (n + 1), 2 * n * n, 0;
  for (j = 0; j <= n; ++j) for (i = 0; i <= n; ++i) print i, j, 0.3 * sin(i * 0.7) * cos(j * 0.4);
  for (j = 0; j < n; ++j) for (i = 0; i < n; ++i) { a = j * (n + 1) + i; b = a + 1;
    c = a + n + 1; d = c + 1; print 3, a, b, d; print 3, a, d, c } }' > "$work/grid.off"

# Attached, for reference.
"$mlclust" mesh "$data/fandisk.off" --server "$server" --algo ml --clusters 50 \
  --labels "$work/attached.labels" --levels-csv "$work/attached.csv" --ply "$work/attached.ply" \
  --quiet > /dev/null || fail "attached run"

# Detached: the id is the last line; outputs are refused with --detach.
"$mlclust" mesh "$data/fandisk.off" --server "$server" --algo ml --detach > "$work/detach.out" \
  || fail "--detach failed"
id=$(tail -1 "$work/detach.out")
[[ "$id" =~ ^job-[0-9a-f]{32}$ ]] || fail "--detach: last line '$id' is not a job id"
grep -q "mlclust watch $id" "$work/detach.out" || fail "--detach: no hint: $(cat "$work/detach.out")"
if "$mlclust" mesh "$data/fandisk.off" --server "$server" --detach --clusters 5 \
  --labels "$work/x" 2> "$work/detach.err"; then fail "--detach with --labels accepted"; fi
grep -q "mlclust watch" "$work/detach.err" || fail "--detach --labels: $(cat "$work/detach.err")"
if "$mlclust" mesh "$data/fandisk.off" --server "$server" --detach --clusters 5 \
  --preview "$work/x.png" 2> "$work/detach.err"; then fail "--detach with --preview accepted"; fi
grep -q -- "--preview goes to" "$work/detach.err" || fail "--detach --preview: $(cat "$work/detach.err")"
if "$mlclust" mesh "$data/fandisk.off" --detach 2> "$work/detach.err"; then
  fail "--detach without --server accepted"
fi
grep -q "needs --server" "$work/detach.err" || fail "--detach alone: $(cat "$work/detach.err")"

# Watch: the same labels, levels and coloured mesh as the attached run.
"$mlclust" watch "$id" --server "$server" --clusters 50 --labels "$work/watched.labels" \
  --levels-csv "$work/watched.csv" --ply "$work/watched.ply" --mesh "$data/fandisk.off" \
  --quiet > "$work/watch.out" || fail "watch failed"
cmp -s "$work/attached.labels" "$work/watched.labels" || fail "watched labels differ"
cmp -s "$work/attached.csv" "$work/watched.csv" || fail "watched levels differ"
cmp -s "$work/attached.ply" "$work/watched.ply" || fail "watched ply differs"
grep -q "levels 0 to 12945" "$work/watch.out" || fail "watch summary: $(cat "$work/watch.out")"
# From level 12,000: the rows of the attached CSV from there on, the same labels at 50.
"$mlclust" watch "$id" --server "$server" --from-level 12000 --clusters 50 \
  --labels "$work/from.labels" --levels-csv "$work/from.csv" --json > "$work/from.json" \
  || fail "watch --from-level failed"
cmp -s "$work/attached.labels" "$work/from.labels" || fail "--from-level labels differ"
diff <(tail -n +12002 "$work/attached.csv") <(tail -n +2 "$work/from.csv") > /dev/null \
  || fail "--from-level levels differ"
/usr/bin/python3 -c '
import json, sys
s = json.load(open(sys.argv[1]))
assert s["first_level"] == 12000 and s["levels"] == 946 and s["level"]["clusters"] == 50, s
' "$work/from.json" || fail "watch --json: $(cat "$work/from.json")"

# jobs: both, with their state (the server lists every connection's: --list-all-jobs); --json
# parses.
"$mlclust" jobs --server "$server" > "$work/jobs.txt" || fail "jobs failed"
grep -q "^$id .*succeeded .*ml .*yes" "$work/jobs.txt" || fail "jobs: $(cat "$work/jobs.txt")"
"$mlclust" jobs --server "$server" --json > "$work/jobs.json" || fail "jobs --json failed"
/usr/bin/python3 -c '
import json, sys
jobs = json.load(open(sys.argv[1]))["jobs"]
assert len(jobs) == 2 and jobs[1]["job_id"] == sys.argv[2] and jobs[1]["detached"], jobs
assert all(j["state"] == "succeeded" for j in jobs), jobs' "$work/jobs.json" "$id" \
  || fail "jobs --json: $(cat "$work/jobs.json")"

# cancel: a long job, then a queued one behind it.
long=$("$mlclust" mesh "$work/grid.off" --server "$server" --algo ml --detach --quiet | tail -1)
queued=$("$mlclust" mesh "$data/fandisk.off" --server "$server" --detach --quiet | tail -1)
[ "$("$mlclust" cancel "$queued" --server "$server")" = "$queued: cancelled" ] \
  || fail "cancel of the queued job"
# Again, as JSON (an ended job keeps its state; --quiet is accepted as by watch).
"$mlclust" cancel "$queued" --server "$server" --json -q > "$work/cancel.json" \
  || fail "cancel --json"
/usr/bin/python3 -c '
import json, sys
j = json.load(open(sys.argv[1]))
assert j == {"job_id": sys.argv[2], "state": "cancelled"}, j' "$work/cancel.json" "$queued" \
  || fail "cancel --json: $(cat "$work/cancel.json")"
if "$mlclust" watch "$queued" --server "$server" --quiet 2> "$work/cancelled.err"; then
  fail "watching a cancelled job succeeded"
fi
grep -q "cancelled by a Cancel call" "$work/cancelled.err" || fail "$(cat "$work/cancelled.err")"
"$mlclust" cancel "$long" --server "$server" > /dev/null || fail "cancel of the running job"

# --deadline: a watch that cannot finish in time says so (the job runs on); a Run is cancelled.
slow=$("$mlclust" mesh "$work/grid.off" --server "$server" --algo ml --detach --quiet | tail -1)
if "$mlclust" watch "$slow" --server "$server" --deadline 0.2 --quiet 2> "$work/deadline.err"; then
  fail "a 0.2 s watch of a long job succeeded"
fi
grep -q "did not finish within --deadline 200ms" "$work/deadline.err" \
  || fail "watch --deadline: $(cat "$work/deadline.err")"
grep -q "runs on" "$work/deadline.err" || fail "watch --deadline: $(cat "$work/deadline.err")"
"$mlclust" cancel "$slow" --server "$server" > /dev/null
if "$mlclust" mesh "$work/grid.off" --server "$server" --algo ml --deadline 0.3 --quiet \
  2> "$work/deadline.err"; then fail "a 0.3 s run of the big grid succeeded"; fi
grep -q "the job did not finish within --deadline 300ms; the server cancelled the job" \
  "$work/deadline.err" || fail "mesh --deadline: $(cat "$work/deadline.err")"
if "$mlclust" jobs --server "$server" --deadline -1 2> "$work/deadline.err"; then
  fail "--deadline -1 accepted"
fi
grep -q "not a number of seconds" "$work/deadline.err" || fail "$(cat "$work/deadline.err")"

# Unknown, and dropped after the retention time (3 s).
if "$mlclust" watch job-777777 --server "$server" 2> "$work/unknown.err"; then
  fail "an unknown job was watched"
fi
grep -q "no job 'job-777777'" "$work/unknown.err" || fail "$(cat "$work/unknown.err")"
sleep 4.5
if "$mlclust" watch "$id" --server "$server" --quiet 2> "$work/dropped.err"; then
  fail "a dropped job was watched"
fi
grep -q "retention time" "$work/dropped.err" || fail "dropped: $(cat "$work/dropped.err")"

kill -TERM "$server_pid"
wait "$server_pid" || fail "server exited with an error on SIGTERM"
server_pid=""
# TLS and tokens: the right credentials work; no token, a wrong one, another tenant's job
# and plaintext are refused; the server never logs a token.
( cd "$work" && openssl req -x509 -newkey rsa:2048 -nodes -keyout server.key -out server.pem \
    -days 1 -subj /CN=localhost -addext subjectAltName=DNS:localhost,IP:127.0.0.1 ) \
  > /dev/null 2>&1 || fail "openssl could not make a certificate"
printf '# tenants\nalpha-secret-0123456789 alpha\nbeta-secret-0123456789 beta\n' > "$work/tokens"
printf 'alpha-secret-0123456789\n' > "$work/alpha.token"
printf 'beta-secret-0123456789\n' > "$work/beta.token"
printf 'wrong-secret-0123456789\n' > "$work/wrong.token"
port=$((20000 + RANDOM % 20000))
"$mlclust" serve --listen "127.0.0.1:$port" --gpu off --tls-cert "$work/server.pem" \
  --tls-key "$work/server.key" --auth-token-file "$work/tokens" 2> "$work/tls_server.log" &
server_pid=$!
for _ in $(seq 100); do
  grep -q "serving" "$work/tls_server.log" 2>/dev/null && break
  sleep 0.1
done
grep -q "bearer tokens on (2)" "$work/tls_server.log" || fail "TLS server: $(cat "$work/tls_server.log")"
server="127.0.0.1:$port"
tls=(--server "$server" --tls-ca "$work/server.pem")
"$mlclust" mesh "$data/fandisk.off" "${tls[@]}" --auth-token-file "$work/alpha.token" --algo hc \
  --clusters 100 --labels "$work/tls.labels" --quiet > /dev/null || fail "TLS + token run failed"
"$mlclust" mesh "$data/fandisk.off" --algo hc --clusters 100 --labels "$work/plain.labels" \
  --quiet > /dev/null
cmp -s "$work/tls.labels" "$work/plain.labels" || fail "TLS labels differ"
tid=$("$mlclust" mesh "$data/fandisk.off" "${tls[@]}" --auth-token-file "$work/alpha.token" \
  --detach --quiet | tail -1)
"$mlclust" watch "$tid" "${tls[@]}" --auth-token-file "$work/alpha.token" --quiet > /dev/null \
  || fail "TLS watch by its tenant failed"
if "$mlclust" watch "$tid" "${tls[@]}" --auth-token-file "$work/beta.token" 2> "$work/t.err"; then
  fail "another tenant watched the job"
fi
# Another tenant's job answers like an id never issued (a tenant cannot count others').
grep -q "no job '$tid' on this server" "$work/t.err" || fail "other tenant: $(cat "$work/t.err")"
if "$mlclust" jobs "${tls[@]}" 2> "$work/t.err"; then fail "jobs without a token"; fi
grep -q "needs a bearer token" "$work/t.err" || fail "no token: $(cat "$work/t.err")"
if "$mlclust" jobs "${tls[@]}" --auth-token-file "$work/wrong.token" 2> "$work/t.err"; then
  fail "a wrong token was accepted"
fi
grep -q "not one this server knows" "$work/t.err" || fail "wrong token: $(cat "$work/t.err")"
if "$mlclust" stats --server "$server" 2> /dev/null; then fail "plaintext to the TLS port"; fi
if "$mlclust" jobs --server "$server" --auth-token-file "$work/alpha.token" 2> "$work/t.err"; then
  fail "a token without TLS was sent"
fi
grep -q "needs TLS" "$work/t.err" || fail "token without TLS: $(cat "$work/t.err")"
kill -TERM "$server_pid"
wait "$server_pid" || fail "TLS server exited with an error on SIGTERM"
server_pid=""
if grep -q "secret-0123456789" "$work/tls_server.log"; then fail "a token was logged"; fi
if "$mlclust" serve --listen 127.0.0.1:0 --auth-token-file "$work/tokens" 2> "$work/t.err"; then
  fail "tokens without TLS were accepted by serve"
fi
grep -q "need TLS" "$work/t.err" || fail "serve tokens without TLS: $(cat "$work/t.err")"

echo "jobs_cli_test: all checks passed"
