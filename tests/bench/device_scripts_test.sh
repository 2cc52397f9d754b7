#!/usr/bin/env bash
# The GPU-node scripts (bench/gpu_node.sh, bench/device_bundle.sh, bench/device_run.sh)
# without a GPU, a bundle or the real binaries: syntax; the row lists (unique ids, two
# parts, part 1 and part 2 each fitting one device call); and gpu_node.sh's budget logic on
# fake binaries (a row over its time is killed and marked, a row that no longer fits is
# skipped, a missing binary or flag skips its row, every row's output is in the CSV).
#   tests/bench/device_scripts_test.sh [REPO_ROOT]
set -uo pipefail
root="${1:-$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)}"
cd "$root" || exit 1
failures=0
fail() { echo "FAIL: $*" >&2; failures=$((failures + 1)); }
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

# 1. Syntax.
for script in bench/gpu_node.sh bench/device_bundle.sh bench/device_run.sh; do
  bash -n "$script" || fail "bash -n $script"
done

# 2. The row lists. Each part must leave room in `device_run.sh --budget 540` for the set-up
# (2-6 s here: loaders, renderer check, armadillo_1m made again in 2-4 s; BENCHMARKS.md) and
# device_run.sh's 10 s for the last copies: 480 s keeps 60 s, most of it for estimates that
# turn out low.
total_of() { sed -n 's/^total estimate: \([0-9]*\)s.*/\1/p'; }
count=0
for part in 1 2 3; do
  node="$(bash bench/gpu_node.sh --dry-run --part "$part" --threads 16 | total_of)"
  quick="$(bash bench/gpu_node.sh --dry-run --quick --part "$part" | total_of)"
  [ "${node:-999}" -le 480 ] || fail "part $part estimate '${node}' s over 480 s"
  [ "${quick:-999}" -le 300 ] || fail "part $part --quick estimate '${quick}' s over 300 s"
  n="$(bash bench/gpu_node.sh --dry-run --part "$part" | grep -c "^$part ")"
  [ "$n" -ge 5 ] || fail "part $part has only $n rows"
  count=$((count + n))
done
ids="$(bash bench/gpu_node.sh --dry-run --part all | awk 'NR > 1 && $1 ~ /^[123]$/ { print $2 }')"
[ "$(echo "$ids" | sort | uniq -d)" = "" ] || fail "duplicate row ids: $(echo "$ids" | sort | uniq -d)"
[ "$count" = "$(echo "$ids" | wc -l)" ] || fail "parts 1 + 2 + 3 ($count) != all rows"
bash bench/device_run.sh --dry-run --budget 540 | grep -q '^total estimate' ||
  fail "device_run.sh --dry-run lists no rows"
bash bench/device_run.sh --budget soon >/dev/null 2>&1
[ $? = 2 ] || fail "device_run.sh accepted --budget soon"
OUT="$work/none" bash bench/device_run.sh --bundle "$work" >/dev/null 2>&1 &&
  fail "device_run.sh ran without a bundle"
bash bench/device_bundle.sh --check --out "$work" >/dev/null 2>&1 &&
  fail "device_bundle.sh --check passed an empty folder"

# 3. The budget logic on fake binaries: each prints a CSV line and sleeps FAKE_SLEEP_<name>.
mkdir -p "$work/build/bench" "$work/build/gpu"
cat >"$work/fake" <<'FAKE'
#!/usr/bin/env bash
name="$(basename "$0")"
echo "fake,$name,$*"
eval "sleep \${FAKE_SLEEP_$name:-0}"
FAKE
chmod +x "$work/fake"
for name in gpu_stages_bench pml_gpu_bench pml_cpu_bench points_bench points_gpu_bench; do
  cp "$work/fake" "$work/build/bench/$name"
done
printf '#!/bin/sh\necho "renderer:  fake"\n' >"$work/build/gpu/mlclust-gpu-info"
chmod +x "$work/build/gpu/mlclust-gpu-info"
# bb-small-klow (quick estimate >= 1 s) runs under a 4 s limit and sleeps 30: killed; then
# bb-small-khigh has no time left: skipped; hc-gpu-meshes has no binary: skipped.
start=$SECONDS
FAKE_SLEEP_gpu_stages_bench=30 bash bench/gpu_node.sh --quick --build "$work/build" \
  --only bb-small-klow,bb-small-khigh,hc-gpu-meshes --budget 4 --out "$work/out" >/dev/null 2>&1 ||
  fail "gpu_node.sh exited non-zero on the fake build"
took=$((SECONDS - start))
[ "$took" -le 15 ] || fail "the budget did not stop the row ($took s)"
status="$work/out/gpu_node_status.tsv"
grep -q $'^bb-small-klow\t1\ttimeout: budget' "$status" || fail "no timeout for bb-small-klow"
grep -q $'^bb-small-khigh\t1\tskipped: budget' "$status" || fail "bb-small-khigh not skipped"
grep -q $'^hc-gpu-meshes\t2\tskipped: no .*hc_gpu_bench' "$status" || fail "hc-gpu-meshes not skipped"
grep -q '^fake,gpu_stages_bench,bb .*fandisk.off --k 100 ' "$work/out/gpu_node.csv" ||
  fail "the killed row's output is not in the CSV"
grep -q 'renderer:  fake' "$work/out/gpu_node.csv" || fail "no renderer in the CSV"
# A row far over its estimate is cut at 3x it (estimate + GPU_NODE_ROW_SLACK at least) even
# with budget left: bb-small-klow's 2 s give 6 s here, of a 100 s budget.
start=$SECONDS
FAKE_SLEEP_gpu_stages_bench=30 GPU_NODE_ROW_SLACK=1 bash bench/gpu_node.sh --quick \
  --build "$work/build" --only bb-small-klow --budget 100 --out "$work/cap" >/dev/null 2>&1
took=$((SECONDS - start))
grep -q $'^bb-small-klow\t1\ttimeout: 3x its estimate' "$work/cap/gpu_node_status.tsv" ||
  fail "bb-small-klow not cut at 3x its estimate"
[ "$took" -le 20 ] || fail "the row cap did not stop the row ($took s)"
# Without a budget every selected row runs; a guard on a string the binary lacks skips.
bash bench/gpu_node.sh --quick --build "$work/build" --part 1 --out "$work/all" >/dev/null 2>&1 ||
  fail "gpu_node.sh --part 1 on the fake build"
ran="$(grep -c $'\tok\t' "$work/all/gpu_node_status.tsv")"
[ "$ran" -ge 10 ] || fail "only $ran rows of part 1 ran on the fake build"
[ "$(grep -c '^fake,' "$work/all/gpu_node.csv")" -ge "$ran" ] || fail "rows missing in the CSV"
# A guard on a string the binary lacks (a mode added by later work) skips its row; the
# points ML rows fail when the levels' hash is not the expected one (the fake prints none).
grep -q $'^growth-1m\t1\tskipped: no \'growth MESH\' in gpu_stages_bench' "$work/all/gpu_node_status.tsv" ||
  fail "growth-1m not skipped on a gpu_stages_bench without the growth mode"
grep -q $'^points-ml-1m-cpu\t1\tfailed: exit 1' "$work/all/gpu_node_status.tsv" ||
  fail "points-ml-1m-cpu did not fail without its hash"
# --check-guards (device_bundle.sh's warnings) names the rows the fake build would skip.
guards="$(bash bench/gpu_node.sh --check-guards --build "$work/build")"
grep -q "row growth-1m (part 1) would be skipped: no 'growth MESH'" <<<"$guards" ||
  fail "--check-guards does not name growth-1m"
grep -q "row hc-gpu-meshes (part 2) would be skipped: no .*hc_gpu_bench" <<<"$guards" ||
  fail "--check-guards does not name hc-gpu-meshes"
grep -q "row pml-gpu-1m-all" <<<"$guards" && fail "--check-guards names a row that can run"

if [ "$failures" = 0 ]; then echo "device scripts: all checks passed"; else exit 1; fi
