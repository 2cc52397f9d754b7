#include "gpu/stages/boundary_based_gpu.h"

#include <type_traits>

#include "absl/strings/str_cat.h"
#include "core/cluster/boundary_based.h"
#include "core/plan/device_policy.h"
#include "gpu/kernels/bb_decide.h"

namespace mlclust::gpu {

// OptimizeBoundaryBased's driver (boundary_based::OptimizeBoundaryBasedWith) with the GPU
// decider as its decide stage.
absl::StatusOr<OptimizeResult> OptimizeBoundaryBasedGpu(GlContext& context,
                                                        const MeshProblem& problem,
                                                        std::vector<ClusterId>& labels,
                                                        const BoundaryBasedOptions& options) {
  if (!HasGpuBoundaryDecide(problem.energy.kind)) {
    return absl::FailedPreconditionError(
        absl::StrCat("BB on the GPU: the energy ", MeshEnergyName(problem.energy.kind),
                     " has no GPU decide stage (cvd, cvd-adaptive, mwcvd-*, planar have)"));
  }
  return boundary_based::OptimizeBoundaryBasedWith(
      problem, labels, options,
      [&](const auto& energy, uint32_t num_clusters,
          const boundary_based::StageThreads& /*threads*/) {
        using Energy = std::decay_t<decltype(energy)>;
        if constexpr (kHasGpuDecide<Energy>) {
          return GpuBoundaryDecider<Energy>::Create(context, energy, *problem.adjacency,
                                                    num_clusters);
        } else {
          return absl::StatusOr<boundary_based::CpuBoundaryDecider<Energy>>(
              absl::InternalError("BB on the GPU: no decide kernel for this energy"));
        }
      });
}

}  // namespace mlclust::gpu
