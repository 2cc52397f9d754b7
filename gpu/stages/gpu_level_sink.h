// What the GPU's PML drivers (multilevel_gpu.cc for meshes, points_multilevel_gpu.cc for
// points; and HC's steps, gpu/stages/mesh_levels_gpu.h) do with a level the GPU computed:
// hand its triplets to the sink.
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
