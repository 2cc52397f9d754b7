// What the GPU's PML drivers (multilevel_gpu.cc for meshes, points_multilevel_gpu.cc for
// points) do with a level the GPU computed: hand its triplets to the sink.
#ifndef MLCLUST_GPU_STAGES_GPU_LEVEL_SINK_H_
#define MLCLUST_GPU_STAGES_GPU_LEVEL_SINK_H_

#include <cstdint>

#include "absl/status/status.h"
#include "core/hierarchy/hierarchy.h"
#include "gpu/kernels/pml_pair_selection.h"

namespace mlclust::gpu {

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
