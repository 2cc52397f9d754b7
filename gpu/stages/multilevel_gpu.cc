#include "gpu/stages/multilevel_gpu.h"

#include <type_traits>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"
#include "core/base/compensated_sum.h"
#include "core/base/status_macros.h"
#include "gpu/kernels/pml_levels.h"

namespace mlclust::gpu {

std::string PmlGpuUnsupported(const MultilevelOptions& options, MeshEnergyKind energy) {
  if (!options.parallel) return "only PML (parallel levels) runs on the GPU";
  if (energy != MeshEnergyKind::kCvd && energy != MeshEnergyKind::kCvdAdaptive) {
    return "the GPU has the merge cost of cvd and cvd-adaptive only";
  }
  if (options.optimizer != MultilevelOptions::Optimizer::kNone) {
    return "the GPU's PML levels are merges only (optimizer none)";
  }
  if (options.p_percent != 0) return "p-percent is not on the GPU";
  if (options.pml_until != 0) return "pml-until (the switch to ML) is not on the GPU";
  return "";
}

absl::StatusOr<MultilevelSummary> RunParallelMultilevelGpu(GlContext& context,
                                                           const MeshProblem& problem,
                                                           const MultilevelOptions& options,
                                                           LevelSink& sink) {
  if (problem.mesh == nullptr || problem.adjacency == nullptr || problem.measures == nullptr) {
    return absl::InvalidArgumentError("mesh problem without mesh, adjacency or measures");
  }
  MLCLUST_RETURN_IF_ERROR(ValidateMeshEnergyOptions(problem.energy));
  if (options.min_clusters < 1) {
    return absl::InvalidArgumentError("clusters: the lowest level must have at least 1");
  }
  const std::string unsupported = PmlGpuUnsupported(options, problem.energy.kind);
  if (!unsupported.empty())
    return absl::UnimplementedError(absl::StrCat("PML on the GPU: ", unsupported));
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "PML set-up"));
  return WithMeshEnergy(
      problem.energy, *problem.mesh, *problem.measures,
      [&](const auto& energy) -> absl::StatusOr<MultilevelSummary> {
        using Energy = std::decay_t<decltype(energy)>;
        if constexpr (!std::is_same_v<Energy, CvdEnergy>) {
          return absl::UnimplementedError("PML on the GPU: not a CVD energy");
        } else {
          const uint32_t n = static_cast<uint32_t>(problem.mesh->num_faces());
          std::vector<CvdSums> face_sums(n);
          for (uint32_t f = 0; f < n; ++f) face_sums[f] = energy.face_sums(f);
          MLCLUST_ASSIGN_OR_RETURN(PmlLevelsGpu levels,
                                   PmlLevelsGpu::Create(context, face_sums, *problem.adjacency));
          std::vector<ClusterId> start(n);
          for (uint32_t f = 0; f < n; ++f) start[f] = ClusterId(f);
          MLCLUST_RETURN_IF_ERROR(sink.OnStart(start, n, 0.0));
          MultilevelSummary summary;
          summary.levels = 1;
          ::mlclust::detail::CompensatedSum energy_sum;
          energy_sum.Reset(0);
          uint32_t clusters = n;
          PmlLevelGpu level;
          while (clusters > options.min_clusters) {
            MLCLUST_RETURN_IF_ERROR(
                CheckCancelled(options.cancel, absl::StrCat("level ", summary.levels)));
            MLCLUST_ASSIGN_OR_RETURN(const bool merged, levels.Level(options.pml_pairs, clusters,
                                                                     options.min_clusters, level));
            if (!merged) break;  // one cluster per component
            clusters -= level.merged;
            energy_sum.Add(level.energy_change);
            LevelMoves moves;
            moves.level = summary.levels;
            moves.cluster_count = clusters;
            moves.energy = energy_sum.value();
            moves.element = level.element;
            moves.to_cluster = level.to_cluster;
            moves.from_cluster = level.from_cluster;
            MLCLUST_RETURN_IF_ERROR(sink.OnLevel(moves));
            summary.moves += level.element.size();
            ++summary.levels;
          }
          summary.final_clusters = clusters;
          summary.final_energy = energy_sum.value();
          return summary;
        }
      });
}

}  // namespace mlclust::gpu
