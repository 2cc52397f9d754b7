#!/usr/bin/env bash
# Installs what is needed, builds, and runs the whole test suite (GoogleTest via CTest).
# GPU tests run on whatever EGL device is there: Mesa's llvmpipe on a machine without a GPU.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
# The CGAL meshes some tests read (data/bench/, ignored by git; libcgal-demo from Debian).
bash scripts/fetch-bench-meshes.sh --no-1m
bash scripts/build.sh
ctest --test-dir build --output-on-failure --parallel "$(nproc)" --timeout 900
