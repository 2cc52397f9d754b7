#!/usr/bin/env bash
# The main job on a bundled sample: installs what is needed, builds the one program it runs
# (the mlclust CLI: scripts/build.sh with MLCLUST_TARGETS=mlclust, 99 of the 298 build steps;
# the same CMake options as scripts/test.sh, so a later test.sh in the same build directory
# reuses what was built here), and computes the whole multilevel (ML) CVD hierarchy of
# data/fandisk.off (12,946 faces) with the embedded server, writing the level with 100
# clusters. Outputs go to out/. MLCLUST_BUILD_DIR chooses the build directory (default build/).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
MLCLUST_TARGETS=mlclust bash scripts/build.sh
mlclust="${MLCLUST_BUILD_DIR:-build}/client/mlclust"
mkdir -p out
"$mlclust" mesh data/fandisk.off --algo ml --energy cvd --clusters 100 \
  --labels out/fandisk_100.labels --levels-csv out/fandisk_levels.csv --ply out/fandisk_100.ply \
  --coarse out/fandisk_100_coarse.obj
echo "energy recomputed from out/fandisk_100.labels and the mesh file:"
"$mlclust" energy data/fandisk.off --labels out/fandisk_100.labels
echo
echo "outputs in $(pwd)/out:"
echo "  fandisk_100.labels   cluster (0..99) of each of the 12,946 faces, one per line"
echo "  fandisk_levels.csv   clusters,energy for every level of the hierarchy"
echo "  fandisk_100.ply      the mesh coloured by cluster (MeshLab, Blender)"
echo "  fandisk_100_coarse.obj  the coarse mesh: one vertex per cluster"
