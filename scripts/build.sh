#!/usr/bin/env bash
# Configures and builds mlclust into build/ (Release). Extra arguments go to CMake.
set -euo pipefail
cd "$(dirname "$0")/.."
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DMLCLUST_WITH_GPU=ON \
  -DMLCLUST_WITH_SERVER=ON -DMLCLUST_BUILD_TESTS=ON -DMLCLUST_BUILD_BENCH=ON "$@"
cmake --build build --parallel "$(nproc)"
