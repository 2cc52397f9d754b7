#!/usr/bin/env bash
# Configures and builds mlclust (Release) with every part on: GPU, server, tests, benches.
# Extra arguments go to CMake's configure step. MLCLUST_BUILD_DIR chooses the build
# directory (default build/). MLCLUST_TARGETS, a space-separated list, builds only those
# targets and what they need (scripts/demo.sh: mlclust); by default everything is built.
# Every caller configures with the same options, so one build directory serves them all.
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir="${MLCLUST_BUILD_DIR:-build}"
cmake -S . -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=Release -DMLCLUST_WITH_GPU=ON \
  -DMLCLUST_WITH_SERVER=ON -DMLCLUST_BUILD_TESTS=ON -DMLCLUST_BUILD_BENCH=ON "$@"
targets=()
if [[ -n "${MLCLUST_TARGETS:-}" ]]; then
  read -r -a names <<< "$MLCLUST_TARGETS"
  targets=(--target "${names[@]}")
fi
cmake --build "$build_dir" --parallel "$(nproc)" "${targets[@]}"
