#include "gpu/stages/gl_device_stages.h"

#include "gpu/stages/boundary_based_gpu.h"

namespace mlclust::gpu {

bool GlDeviceStages::HasBoundaryDecide(MeshEnergyKind energy) const {
  return HasGpuBoundaryDecide(energy);
}

absl::StatusOr<OptimizeResult> GlDeviceStages::OptimizeBoundaryBased(
    const MeshProblem& problem, std::vector<ClusterId>& labels,
    const BoundaryBasedOptions& options) {
  return OptimizeBoundaryBasedGpu(context_, problem, labels, options);
}

}  // namespace mlclust::gpu
