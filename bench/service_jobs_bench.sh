#!/usr/bin/env bash
# Detached jobs, TLS and metrics, measured with the CLI against one `mlclust serve` on
# loopback (CPU only, one worker): an attached run; the same job detached and watched after
# it ended (the whole hierarchy, and from a late level); the memory its kept levels take;
# the same run over TLS with a bearer token; one /metrics scrape.
#   bench/service_jobs_bench.sh MLCLUST_BINARY MESH [ALGO] [REPEATS]
set -euo pipefail
mlclust=$1
mesh=$2
algo=${3:-hc}
repeats=${4:-3}
work=$(mktemp -d)
pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null; wait "$p" 2>/dev/null; done; rm -rf "$work"; }
trap cleanup EXIT
py=/usr/bin/python3

start_server() {  # NAME ARGS...: starts `mlclust serve`, sets $port
  local name=$1; shift
  port=$((20000 + RANDOM % 20000))
  "$mlclust" serve --listen "127.0.0.1:$port" --gpu off "$@" 2> "$work/$name.log" &
  pids+=($!)
  for _ in $(seq 200); do grep -q "serving" "$work/$name.log" 2>/dev/null && return; sleep 0.05; done
  echo "server $name did not start: $(cat "$work/$name.log")" >&2; exit 1
}
seconds() {  # runs "$@" quietly, prints its wall time in seconds
  local t0 t1
  t0=$(date +%s.%N); "$@" > /dev/null; t1=$(date +%s.%N)
  echo "$t0 $t1" | awk '{ printf "%.3f", $2 - $1 }'
}
median() { tr ' ' '\n' | sort -g | awk '{ v[NR] = $1 } END { print v[int((NR + 1) / 2)] }'; }

mport=$((20000 + RANDOM % 20000))
start_server plain --list-all-jobs --metrics "127.0.0.1:$mport"
plain=$port
( cd "$work" && openssl req -x509 -newkey rsa:2048 -nodes -keyout k.pem -out c.pem -days 1 \
    -subj /CN=localhost -addext subjectAltName=IP:127.0.0.1 ) > /dev/null 2>&1
printf 'bench-token-0123456789 bench\n' > "$work/tokens"
start_server tls --tls-cert "$work/c.pem" --tls-key "$work/k.pem" --auth-token-file "$work/tokens"
tls=$port

"$mlclust" mesh "$mesh" --server "127.0.0.1:$plain" --algo "$algo" --quiet > /dev/null  # warm-up
attached=() detached=() watch_all=() watch_late=() tls_runs=()
for _ in $(seq "$repeats"); do
  attached+=("$(seconds "$mlclust" mesh "$mesh" --server "127.0.0.1:$plain" --algo "$algo" --quiet)")
  tls_runs+=("$(seconds "$mlclust" mesh "$mesh" --server "127.0.0.1:$tls" --algo "$algo" --quiet \
    --tls-ca "$work/c.pem" --auth-token-file "$work/tokens")")
  t0=$(date +%s.%N)
  id=$("$mlclust" mesh "$mesh" --server "127.0.0.1:$plain" --algo "$algo" --detach --quiet | tail -1)
  "$mlclust" watch "$id" --server "127.0.0.1:$plain" --quiet > /dev/null  # follows it to the end
  t1=$(date +%s.%N)
  detached+=("$(echo "$t0 $t1" | awk '{ printf "%.3f", $2 - $1 }')")
  watch_all+=("$(seconds "$mlclust" watch "$id" --server "127.0.0.1:$plain" --quiet)")
  levels=$("$mlclust" jobs --server "127.0.0.1:$plain" --json | $py -c '
import json, sys; print([j for j in json.load(sys.stdin)["jobs"] if j["job_id"] == sys.argv[1]][0]["levels"])' "$id")
  watch_late+=("$(seconds "$mlclust" watch "$id" --server "127.0.0.1:$plain" --quiet \
    --from-level $((levels - 100)))")
done
"$mlclust" jobs --server "127.0.0.1:$plain" --json > "$work/jobs.json"
scrape=$($py - "$mport" <<'PY'
import sys, time, urllib.request
url = f"http://127.0.0.1:{sys.argv[1]}/metrics"
urllib.request.urlopen(url).read()
t = time.perf_counter(); n = 20
for _ in range(n): body = urllib.request.urlopen(url).read()
print(f"{(time.perf_counter() - t) / n * 1000:.2f} ms, {len(body)} bytes")
PY
)
$py - "$work/jobs.json" <<'PY'
import json, sys
jobs = [j for j in json.load(open(sys.argv[1]))["jobs"] if j["detached"]]
j = jobs[-1]
triplets, levels, kept = int(j["triplets"]), int(j["levels"]), int(j["kept_bytes"])
print(f"kept levels of one detached job: {kept / 2**20:.2f} MiB for {levels} levels and "
      f"{triplets} triplets ({kept / max(1, triplets):.1f} bytes per triplet, labels and levels included)")
PY
echo "attached run (s):              $(echo "${attached[*]}" | median)  [${attached[*]}]"
echo "detach + watch to the end (s): $(echo "${detached[*]}" | median)  [${detached[*]}]"
echo "watch of the ended job (s):    $(echo "${watch_all[*]}" | median)  [${watch_all[*]}]"
echo "watch from 100 levels before the end (s): $(echo "${watch_late[*]}" | median)  [${watch_late[*]}]"
echo "attached run over TLS + token (s): $(echo "${tls_runs[*]}" | median)  [${tls_runs[*]}]"
echo "one /metrics scrape: $scrape"
