#!/usr/bin/env bash
# The cost of choosing a replica (client/replicas.h): wall time of one CLI job (fandisk, ml,
# CPU) through one server, a list of three, a list whose first (in order) is gone, and a
# list of three with one frozen (SIGSTOP: its GetStats probe waits the 2 s limit).
#   bench/replicas_overhead.sh [MLCLUST_BINARY] [DATA_DIR]
set -u
M=${1:-build/client/mlclust}; D=${2:-data}
base=$((40000 + RANDOM % 10000)); pids=()
for i in 0 1 2; do "$M" serve --listen 127.0.0.1:$((base+i)) --gpu off 2>/dev/null & pids+=($!); done
sleep 1.5
a=127.0.0.1:$base b=127.0.0.1:$((base+1)) c=127.0.0.1:$((base+2)) dead=127.0.0.1:$((base+9))
frozen_pid=${pids[2]}
t() { local s=$(date +%s.%N); "$M" mesh "$D/fandisk.off" --algo ml --quiet "$@" >/dev/null 2>&1 || echo FAIL; echo "$(date +%s.%N) - $s" | bc; }
med() { sort -n | awk '{v[NR]=$1} END {print v[int((NR+1)/2)]}'; }
for mode in single list3 dead-first-in-order; do
  for r in 1 2 3 4 5 6 7; do
    case $mode in
      single) t --server "$a";;
      list3) t --server "$a,$b,$c";;
      dead-first-in-order) t --server "$dead,$a,$b" --spread in-order;;
    esac
  done | med | xargs printf "%-28s median of 7: %.3f s\n" "$mode"
done
kill -STOP $frozen_pid
for r in 1 2 3; do t --server "$a,$b,$c"; done | med | xargs printf "%-28s median of 3: %.3f s\n" "list3, one frozen (SIGSTOP)"
kill -CONT $frozen_pid
for p in "${pids[@]}"; do kill $p; done; wait 2>/dev/null
