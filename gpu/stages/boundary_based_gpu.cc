#include "gpu/stages/boundary_based_gpu.h"

#include <type_traits>

#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"
#include "core/base/renumber.h"
#include "core/base/status_macros.h"
#include "core/cluster/boundary_based.h"
#include "core/mesh/connectivity_guard.h"
#include "gpu/kernels/bb_decide.h"

namespace mlclust::gpu {

bool HasGpuBoundaryDecide(MeshEnergyKind energy) {
  switch (energy) {
    case MeshEnergyKind::kCvd:
    case MeshEnergyKind::kCvdAdaptive:
    case MeshEnergyKind::kMwcvdArea:
    case MeshEnergyKind::kMwcvdVariance:
    case MeshEnergyKind::kMwcvdMax:
    case MeshEnergyKind::kPlanar:
      return true;
    default:
      return false;
  }
}

// The set-up is OptimizeBoundaryBased's (core/cluster/mesh_clustering.cc): compact labels,
// a partition, the connectivity guard; then RunBoundaryBased with the GPU decider.
absl::StatusOr<OptimizeResult> OptimizeBoundaryBasedGpu(GlContext& context,
                                                        const MeshProblem& problem,
                                                        std::vector<ClusterId>& labels,
                                                        const BoundaryBasedOptions& options) {
  MLCLUST_RETURN_IF_ERROR(ValidateMeshProblem(problem));
  if (!HasGpuBoundaryDecide(problem.energy.kind)) {
    return absl::FailedPreconditionError(
        absl::StrCat("BB on the GPU: the energy ", MeshEnergyName(problem.energy.kind),
                     " has no GPU decide stage (cvd, cvd-adaptive, mwcvd-*, planar have)"));
  }
  const size_t n = problem.mesh->num_faces();
  if (labels.size() != n) {
    return absl::InvalidArgumentError(
        absl::StrCat("labels: ", labels.size(), " for a mesh of ", n, " faces"));
  }
  if (options.threads < 0) {
    return absl::InvalidArgumentError(absl::StrCat("threads: ", options.threads, " < 0"));
  }
  const Renumbering<ClusterId> renumbered =
      RenumberByFirstAppearance(std::span<const ClusterId>(labels));
  const uint32_t k = renumbered.size();
  const boundary_based::StageThreads threads(options.threads);
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "BB set-up"));
  auto run = [&](const auto& energy) -> absl::StatusOr<OptimizeResult> {
    using Energy = std::decay_t<decltype(energy)>;
    if constexpr (!kHasGpuDecide<Energy>) {
      return absl::InternalError("BB on the GPU: no decide kernel for this energy");
    } else {
      Partition<Energy> partition(energy, renumbered.dense, k);
      MLCLUST_ASSIGN_OR_RETURN(
          const ConnectivityGuard guard,
          ConnectivityGuard::Build(*problem.mesh, *problem.adjacency, options.cancel));
      MLCLUST_ASSIGN_OR_RETURN(
          GpuBoundaryDecider<Energy> decide,
          GpuBoundaryDecider<Energy>::Create(context, energy, *problem.adjacency, k));
      MLCLUST_ASSIGN_OR_RETURN(
          OptimizeResult result,
          boundary_based::RunBoundaryBased(guard, partition, options, threads, decide));
      const std::span<const uint32_t> compact = partition.labels();
      for (size_t f = 0; f < n; ++f) labels[f] = renumbered.original[compact[f]];
      return result;
    }
  };
  return WithMeshEnergy(problem.energy, *problem.mesh, *problem.measures, run);
}

}  // namespace mlclust::gpu
