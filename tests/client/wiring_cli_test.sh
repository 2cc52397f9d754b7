#!/usr/bin/env bash
# The library pieces wired into the CLI (issues 11 and 13), end to end through the embedded
# server: X-means and bisecting k-means on points.
#   wiring_cli_test.sh MLCLUST_BINARY DATA_DIR
set -euo pipefail
mlclust=$1
data=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

# Five well-separated Gaussian blobs of 100 points in 2-D (sigma 1, centres 20 apart), and
# the blob of each point.
/usr/bin/python3 -c '
import numpy as np, sys
r = np.random.default_rng(1)
c = np.array([[0, 0], [20, 0], [0, 20], [20, 20], [40, 40]], float)
np.save(sys.argv[1], np.concatenate([ci + r.normal(size=(100, 2)) for ci in c]).astype(np.float32))
np.savetxt(sys.argv[2], np.repeat(np.arange(5), 100), fmt="%d")
' "$work/blobs.npy" "$work/truth.txt"

# The same partition as the blobs (labels equal up to renaming).
same_partition() {
  /usr/bin/python3 -c '
import sys
a = [l.strip() for l in open(sys.argv[1])]
b = [l.strip() for l in open(sys.argv[2])]
assert len(a) == len(b), (len(a), len(b))
assert len(set(zip(a, b))) == len(set(a)) == len(set(b)), "partitions differ"
' "$1" "$2"
}

# X-means (Alg. 2.5) from k_min = 1 finds the five blobs; --labels writes the K it found.
"$mlclust" points "$work/blobs.npy" --algo xmeans --clusters 1 --kmax 20 \
  --labels "$work/xmeans.txt" --levels-csv "$work/xmeans.csv" --json --quiet > "$work/xmeans.json"
[ "$(wc -l < "$work/xmeans.txt")" -eq 500 ] || fail "xmeans: not one label per point"
same_partition "$work/xmeans.txt" "$work/truth.txt" || fail "xmeans: not the five blobs"
/usr/bin/python3 -c '
import json, sys
j = json.load(open(sys.argv[1]))
assert j["algorithm"] == "xmeans" and j["final_clusters"] == 5 and j["levels"] == 2, j
assert j["level"]["clusters"] == 5, j
' "$work/xmeans.json" || fail "xmeans: summary $(cat "$work/xmeans.json")"
# Level 0 is the k-means at k_min = 1 (one cluster), level 1 the result.
[ "$(sed -n 2p "$work/xmeans.csv" | cut -d, -f1)" = 1 ] || fail "xmeans: level 0 not at k_min"
[ "$(sed -n 3p "$work/xmeans.csv" | cut -d, -f1)" = 5 ] || fail "xmeans: level 1 not at 5"
# k_max below k_min is a bad argument (exit 2), named.
if "$mlclust" points "$work/blobs.npy" --algo xmeans --clusters 5 --kmax 3 --quiet \
  2> "$work/kmax.err"; then
  fail "xmeans: kmax < k_min accepted"
else
  [ $? -eq 2 ] || fail "xmeans: kmax < k_min: exit not 2"
fi
grep -q "kmax" "$work/kmax.err" || fail "xmeans: no message naming kmax: $(cat "$work/kmax.err")"

# Bisecting k-means (Alg. 2.7): levels from K = 8 down to 1; the level with 5 clusters,
# splitting the cluster of largest energy with the best of 5 k-means++ 2-means (a cut made
# early is never undone: with one random 2-means a blob is cut),
# is the five blobs.
bisect="--split energy --trials 5 --init kmeans++"
"$mlclust" points "$work/blobs.npy" --algo bisecting --clusters 8 $bisect \
  --levels-csv "$work/bisecting.csv" --quiet > /dev/null
[ "$(cut -d, -f1 "$work/bisecting.csv" | tr '\n' ' ')" = "clusters 8 7 6 5 4 3 2 1 " ] \
  || fail "bisecting: levels $(cut -d, -f1 "$work/bisecting.csv" | tr '\n' ' ')"
"$mlclust" points "$work/blobs.npy" --algo bisecting --clusters 5 $bisect \
  --labels "$work/bisecting.txt" --quiet > /dev/null
same_partition "$work/bisecting.txt" "$work/truth.txt" || fail "bisecting: not the five blobs"
# A hierarchy: --auto-k bic picks a level (the five blobs score highest among 8..1).
"$mlclust" points "$work/blobs.npy" --algo bisecting --clusters 8 $bisect --auto-k bic \
  --labels "$work/bic.txt" --quiet > "$work/bic.out"
same_partition "$work/bic.txt" "$work/truth.txt" || fail "bisecting --auto-k bic: $(cat "$work/bic.out")"
# Without K: a bad argument.
if "$mlclust" points "$work/blobs.npy" --algo bisecting --quiet 2> "$work/nok.err"; then
  fail "bisecting without --clusters accepted"
fi
grep -q "clusters" "$work/nok.err" || fail "bisecting: no message naming --clusters"

echo "PASS"
