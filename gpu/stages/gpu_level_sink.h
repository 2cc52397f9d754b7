// What the GPU's hierarchy drivers (hierarchy_gpu.cc and multilevel_gpu.cc for meshes,
// points_multilevel_gpu.cc for points) share: the mesh start of one cluster per face, and
// a level the GPU computed handed to the sink.
#ifndef MLCLUST_GPU_STAGES_GPU_LEVEL_SINK_H_
#define MLCLUST_GPU_STAGES_GPU_LEVEL_SINK_H_

#include <cstdint>
#include <vector>

#include "absl/status/status.h"
#include "core/base/ids.h"
#include "core/energy/energies.h"
#include "core/hierarchy/hierarchy.h"
#include "gpu/kernels/pml_pair_selection.h"

namespace mlclust::gpu {

// The CVD sums of the first `n` faces (the GPU's start: one cluster per face).
inline std::vector<CvdSums> CvdFaceSums(const CvdEnergy& energy, uint32_t n) {
  std::vector<CvdSums> sums(n);
  for (uint32_t f = 0; f < n; ++f) sums[f] = energy.face_sums(f);
  return sums;
}

// sink.OnStart with every one of `n` faces its own cluster (id = face), energy 0.
inline absl::Status SendFacesAsClusters(uint32_t n, LevelSink& sink) {
  std::vector<ClusterId> start(n);
  for (uint32_t f = 0; f < n; ++f) start[f] = ClusterId(f);
  return sink.OnStart(start, n, 0.0);
}

// sink.OnLevel with `level`'s triplets as level `number`, `clusters` clusters after it and
// the energy `energy` (the caller's running sum).
inline absl::Status SendGpuLevel(const GpuPmlLevel& level, uint32_t number, uint32_t clusters,
                                 double energy, LevelSink& sink) {
  LevelMoves moves;
  moves.level = number;
  moves.cluster_count = clusters;
  moves.energy = energy;
  moves.element = level.element;
  moves.to_cluster = level.to_cluster;
  moves.from_cluster = level.from_cluster;
  return sink.OnLevel(moves);
}

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_STAGES_GPU_LEVEL_SINK_H_
