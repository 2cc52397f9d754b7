#!/usr/bin/env bash
# The CLI's --preview: a PNG of the asked size from the embedded server and from a
# separate `mlclust serve`; a bad --preview-size and misplaced preview options are refused
# with a message and exit status 2. (The picture's colours are checked in
# tests/e2e/preview/preview_test.cc and tests/gpu/render/.)
#   preview_cli_test.sh MLCLUST_BINARY DATA_DIR
source "$(dirname "$0")/cli_lib.sh" "$@"

# "WIDTH HEIGHT" from a PNG's IHDR, after checking the signature.
png_size() {
  /usr/bin/python3 -c '
import struct, sys
data = open(sys.argv[1], "rb").read(33)
assert data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR", "not a PNG"
print(*struct.unpack(">II", data[16:24]))' "$1"
}

# Embedded: fandisk at 40 clusters.
"$mlclust" mesh "$data/fandisk.off" --clusters 40 --preview "$work/fandisk.png" \
  --preview-size 400x300 --quiet > "$work/embedded.out" || fail "embedded --preview failed"
[ "$(png_size "$work/fandisk.png")" = "400 300" ] || fail "embedded preview: $(png_size "$work/fandisk.png")"
grep -q "preview 400x300 of 40 clusters" "$work/embedded.out" || fail "summary: $(cat "$work/embedded.out")"
"$mlclust" mesh "$data/fandisk.off" --clusters 40 --preview "$work/j.png" --json --quiet \
  > "$work/summary.json" || fail "--json with --preview failed"
/usr/bin/python3 -c 'import json, sys; assert json.load(open(sys.argv[1]))["outputs"]["preview"]' \
  "$work/summary.json" || fail "--json does not name the preview: $(cat "$work/summary.json")"

# A separate server; the default size.
port=$((20000 + RANDOM % 20000))
start_server "$work/server.log" --listen "127.0.0.1:$port"
"$mlclust" mesh "$data/fandisk.off" --server "127.0.0.1:$port" --algo pml --clusters 25 \
  --preview "$work/remote.png" --quiet > "$work/remote.out" || fail "remote --preview failed"
[ "$(png_size "$work/remote.png")" = "1024 768" ] || fail "remote preview: $(png_size "$work/remote.png")"

# Refusals: exit 2 and a message naming the option.
for size in 0x100 100 abc 5000x100 12x12 800x600x2; do
  status=0
  "$mlclust" mesh "$data/fandisk.off" --clusters 10 --preview "$work/bad.png" \
    --preview-size "$size" --quiet 2> "$work/bad.err" || status=$?
  [ "$status" -eq 2 ] || fail "--preview-size $size: exit $status"
  grep -q -- "--preview-size" "$work/bad.err" || fail "--preview-size $size: $(cat "$work/bad.err")"
  [ ! -e "$work/bad.png" ] || fail "--preview-size $size wrote a file"
done
for view in 35 10,95 a,b; do
  status=0
  "$mlclust" mesh "$data/fandisk.off" --clusters 10 --preview "$work/bad.png" \
    --preview-view "$view" --quiet 2> "$work/bad.err" || status=$?
  [ "$status" -eq 2 ] || fail "--preview-view $view: exit $status"
  grep -q -- "--preview-view" "$work/bad.err" || fail "--preview-view $view: $(cat "$work/bad.err")"
done
"$mlclust" mesh "$data/fandisk.off" --clusters 10 --preview "$work/turned.png" \
  --preview-view 215,20 --preview-size 64x64 --quiet > /dev/null || fail "--preview-view 215,20 failed"
[ "$(png_size "$work/turned.png")" = "64 64" ] || fail "turned preview: $(png_size "$work/turned.png")"
status=0
"$mlclust" mesh "$data/fandisk.off" --clusters 10 --preview-size 300x200 --quiet \
  2> "$work/alone.err" || status=$?
[ "$status" -eq 2 ] || fail "--preview-size alone: exit $status"
grep -q "needs --preview" "$work/alone.err" || fail "--preview-size alone: $(cat "$work/alone.err")"

kill -TERM "$server_pid"
wait "$server_pid" || fail "server exited with an error on SIGTERM"
server_pid=""
echo "preview_cli_test: all checks passed"
