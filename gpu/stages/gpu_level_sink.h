// How a level the GPU computed reaches the sink: its triplets handed over as they are. Used
// by the merges-only mesh levels (MergeLevelReporter, gpu/stages/mesh_levels_gpu.h: HC's
// steps and PML with optimizer none) and by the points' PML (points_multilevel_gpu.cc). The
// mesh levels with BB (multilevel_gpu.cc's RunLevelsWithBoundaryBased) do not use it: their
// merges and moves go through the CPU engine's LevelRecorder::Emit.
#ifndef MLCLUST_GPU_STAGES_GPU_LEVEL_SINK_H_
#define MLCLUST_GPU_STAGES_GPU_LEVEL_SINK_H_

#include <cstdint>
#include <span>

#include "absl/status/status.h"
#include "core/hierarchy/hierarchy.h"
#include "gpu/kernels/pml_pair_selection.h"

namespace mlclust::gpu {

// sink.OnLevel with the triplets (element, to, from) as level `number`, `clusters`
// clusters after it and the energy `energy` (the caller's running sum).
inline absl::Status SendGpuLevel(std::span<const uint32_t> element, std::span<const uint32_t> to,
                                 std::span<const uint32_t> from, uint32_t number, uint32_t clusters,
                                 double energy, LevelSink& sink) {
  return sink.OnLevel(LevelMoves{.level = number,
                                 .cluster_count = clusters,
                                 .energy = energy,
                                 .element = element,
                                 .to_cluster = to,
                                 .from_cluster = from});
}

// The same with `level`'s triplets.
inline absl::Status SendGpuLevel(const GpuPmlLevel& level, uint32_t number, uint32_t clusters,
                                 double energy, LevelSink& sink) {
  return SendGpuLevel(level.element, level.to_cluster, level.from_cluster, number, clusters, energy,
                      sink);
}

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_STAGES_GPU_LEVEL_SINK_H_
