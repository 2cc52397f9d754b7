#!/usr/bin/env bash
# Builds the libFuzzer targets (fuzz/) in build-fuzz with clang-14, ASan and UBSan, and runs
# each for a short bounded time from its seed corpus (fuzz/corpus/<target>/); fails on any
# crash, sanitizer report, leak, timeout or broken fuzz check, leaving the input that did it
# in build-fuzz/artifacts/<target>/. Idempotent: a second run rebuilds only what changed.
#
#   scripts/fuzz-smoke.sh [TARGET...]       default: every target, FUZZ_SECONDS each
#
# Environment: FUZZ_SECONDS (default 15) per target, or FUZZ_RUNS (that many runs from seed
# 1: the same inputs every time); FUZZ_BUILD_DIR (default build-fuzz); FUZZ_JOBS (build
# parallelism, default the number of cores). Inputs the fuzzer finds go to
# build-fuzz/corpus/<target>/, never to the committed seeds. Replay a crash with
#   build-fuzz/fuzz/fuzz_<target> build-fuzz/artifacts/<target>/crash-...
set -euo pipefail
cd "$(dirname "$0")/.."

seconds="${FUZZ_SECONDS:-15}"
build="${FUZZ_BUILD_DIR:-build-fuzz}"
jobs="${FUZZ_JOBS:-$(nproc)}"
all_targets=(draco points_batch off ply npy csv gltf_draco meshlet_file request watch_cancel)
targets=("$@")
[ ${#targets[@]} -eq 0 ] && targets=("${all_targets[@]}")

# libFuzzer comes with Debian 12's clang-14 in libclang-rt-14-dev.
packages=(clang-14 libclang-rt-14-dev)
missing=()
for package in "${packages[@]}"; do
  dpkg -s "$package" > /dev/null 2>&1 || missing+=("$package")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "fuzz-smoke: installing ${missing[*]}"
  sudo=""
  [ "$(id -u)" -ne 0 ] && sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

launcher=()
command -v ccache > /dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
if [ ! -f "$build/build.ninja" ]; then
  CC=clang-14 CXX=clang++-14 cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DMLCLUST_BUILD_FUZZERS=ON -DMLCLUST_WITH_GPU=OFF -DMLCLUST_WITH_SERVER=OFF \
    -DMLCLUST_BUILD_TESTS=OFF -DMLCLUST_BUILD_BENCH=OFF "${launcher[@]}" > /dev/null
fi
ninja -C "$build" -j "$jobs" "${targets[@]/#/fuzz_}"

# Known leaks in system libraries, not in ours: fuzz/lsan.supp.
export LSAN_OPTIONS="suppressions=$PWD/fuzz/lsan.supp${LSAN_OPTIONS:+:$LSAN_OPTIONS}"
export UBSAN_OPTIONS="print_stacktrace=1${UBSAN_OPTIONS:+:$UBSAN_OPTIONS}"
failed=()
for target in "${targets[@]}"; do
  work="$build/corpus/$target"
  artifacts="$build/artifacts/$target"
  mkdir -p "$work" "$artifacts"
  log="$build/fuzz-$target.log"
  # FUZZ_RUNS=N: N executions from a fixed seed (the same inputs every time, as CI needs);
  # otherwise FUZZ_SECONDS of fresh exploration.
  if [ -n "${FUZZ_RUNS:-}" ]; then
    budget=(-runs="$FUZZ_RUNS" -seed=1)
    echo "fuzz-smoke: $target for $FUZZ_RUNS runs (seed 1)"
  else
    budget=(-max_total_time="$seconds")
    echo "fuzz-smoke: $target for ${seconds}s"
  fi
  # New inputs go to the first corpus directory; the seeds are only read.
  if "$build/fuzz/fuzz_$target" "$work" "fuzz/corpus/$target" "${budget[@]}" \
      -timeout=10 -rss_limit_mb=2048 -max_len=8192 -print_final_stats=1 \
      -artifact_prefix="$artifacts/" > "$log" 2>&1; then
    grep -E "^stat::number_of_executed_units" "$log" | sed "s/^/  /" || true
  else
    echo "fuzz-smoke: $target FAILED; the end of $log:" >&2
    tail -n 40 "$log" >&2
    failed+=("$target")
  fi
done
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz-smoke: failed: ${failed[*]} (inputs in $build/artifacts/)" >&2
  exit 1
fi
each="${seconds}s"
[ -n "${FUZZ_RUNS:-}" ] && each="$FUZZ_RUNS runs"
echo "fuzz-smoke: ${#targets[@]} targets, $each each, no crash"
