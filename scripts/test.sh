#!/usr/bin/env bash
# Installs what is needed, builds, and runs the whole test suite (GoogleTest via CTest).
# GPU tests run on whatever EGL device is there: Mesa's llvmpipe on a machine without a GPU.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
bash scripts/build.sh
ctest --test-dir build --output-on-failure --parallel "$(nproc)" --timeout 900
