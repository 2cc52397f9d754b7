#!/usr/bin/env bash
# Issue 13's recipe for Debian's `draco_encoder` (README, For pipelines), checked on fandisk:
# its sequential mode without quantisation (-cl 0 -qp 0) keeps the face order, so the
# labels of the .drc are the labels of the input file, line for line; its default
# (edgebreaker) reorders faces and carries no face id attribute, and the job says so
# (Accepted.face_order, in --json's upload), with the same number of faces.
#   draco_encoder_test.sh MLCLUST_BINARY DATA_DIR
source "$(dirname "$0")/cli_lib.sh" "$@"
command -v draco_encoder > /dev/null \
  || fail "draco_encoder is not installed (scripts/install-deps.sh installs Debian's draco)"

# fandisk as OBJ (draco_encoder reads OBJ and PLY, not OFF): vertices, then 1-based faces.
awk 'NF == 0 || /^#/ { next }
     header == 0 { header = 1; next }
     header == 1 { nv = $1; nf = $2; header = 2; next }
     nv > 0 { print "v", $1, $2, $3; nv--; next }
     nf > 0 { print "f", $2 + 1, $3 + 1, $4 + 1; nf-- }' "$data/fandisk.off" > "$work/fandisk.obj"
draco_encoder -i "$work/fandisk.obj" -o "$work/sequential.drc" -cl 0 -qp 0 > /dev/null \
  || fail "draco_encoder -cl 0 -qp 0 failed"
draco_encoder -i "$work/fandisk.obj" -o "$work/edgebreaker.drc" > /dev/null \
  || fail "draco_encoder (default, edgebreaker) failed"

for input in "$data/fandisk.off" "$work/sequential.drc" "$work/edgebreaker.drc"; do
  name=$(basename "$input")
  "$mlclust" mesh "$input" --algo hc --clusters 50 --labels "$work/$name.labels" --json \
    > "$work/$name.json" 2> "$work/$name.err" || fail "$name: $(cat "$work/$name.err")"
  grep -q '"faces": 12946' "$work/$name.json" || fail "$name: $(cat "$work/$name.json")"
done
cmp -s "$work/fandisk.off.labels" "$work/sequential.drc.labels" \
  || fail "draco_encoder -cl 0 -qp 0: the labels are not those of the OFF file"
grep -q '"face_ids": false' "$work/edgebreaker.drc.json" \
  || fail "edgebreaker: $(cat "$work/edgebreaker.drc.json")"
grep -q 'decoded face order' "$work/edgebreaker.drc.json" \
  || fail "edgebreaker: Accepted does not say the decoded order: $(cat "$work/edgebreaker.drc.json")"
if cmp -s "$work/fandisk.off.labels" "$work/edgebreaker.drc.labels"; then
  fail "edgebreaker: the labels did not move with the faces (the test shows nothing)"
fi
echo "draco_encoder_test: all checks passed"
