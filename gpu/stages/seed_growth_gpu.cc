#include "gpu/stages/seed_growth_gpu.h"

#include <utility>

#include "gpu/kernels/seed_growth.h"

namespace mlclust::gpu {

SeedOptions::DeviceGrowth GpuRoundsGrowth(GlContext& context) {
  return [&context](const FaceAdjacency& adjacency, std::span<const uint32_t> seeds,
                    const std::atomic<bool>* cancel) -> absl::StatusOr<std::vector<uint32_t>> {
    absl::StatusOr<SeedGrowthGpuResult> grown =
        GrowSeedsInRoundsGpu(context, adjacency, seeds, cancel);
    if (!grown.ok()) return grown.status();
    return std::move(grown->labels);
  };
}

absl::StatusOr<std::vector<ClusterId>> InitialClustersGpu(GlContext& context,
                                                          const MeshProblem& problem,
                                                          SeedOptions options) {
  options.device_rounds = GpuRoundsGrowth(context);
  return InitialClusters(problem, options);
}

}  // namespace mlclust::gpu
