#include "gpu/stages/hierarchy_gpu.h"

#include <span>
#include <type_traits>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"
#include "core/base/compensated_sum.h"
#include "core/base/status_macros.h"
#include "gpu/kernels/hc_levels.h"
#include "gpu/stages/gpu_level_sink.h"

namespace mlclust::gpu {

std::string HcGpuUnsupported(const MultilevelOptions& options, MeshEnergyKind energy) {
  if (options.parallel) return "PML's levels are gpu/stages/multilevel_gpu.h's";
  if (energy != MeshEnergyKind::kCvd && energy != MeshEnergyKind::kCvdAdaptive) {
    return "the GPU has the merge cost of cvd and cvd-adaptive only";
  }
  if (options.optimizer != MultilevelOptions::Optimizer::kNone) {
    return "the GPU's levels are merges only (HC: optimizer none)";
  }
  if (options.p_percent != 0) return "p-percent is not on the GPU";
  return "";
}

absl::StatusOr<MultilevelSummary> RunHierarchyGpu(GlContext& context, const MeshProblem& problem,
                                                  const MultilevelOptions& options,
                                                  LevelSink& sink) {
  if (problem.mesh == nullptr || problem.adjacency == nullptr || problem.measures == nullptr) {
    return absl::InvalidArgumentError("mesh problem without mesh, adjacency or measures");
  }
  MLCLUST_RETURN_IF_ERROR(ValidateMeshEnergyOptions(problem.energy));
  if (options.min_clusters < 1) {
    return absl::InvalidArgumentError("clusters: the lowest level must have at least 1");
  }
  std::string unsupported = HcGpuUnsupported(options, problem.energy.kind);
  if (unsupported.empty() && problem.polygons != nullptr) {
    unsupported = "polygons stay on the CPU";
  }
  if (!unsupported.empty())
    return absl::UnimplementedError(absl::StrCat("HC on the GPU: ", unsupported));
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "HC set-up"));
  return WithMeshEnergy(
      problem.energy, *problem.mesh, *problem.measures,
      [&](const auto& energy) -> absl::StatusOr<MultilevelSummary> {
        using Energy = std::decay_t<decltype(energy)>;
        if constexpr (!std::is_same_v<Energy, CvdEnergy>) {
          return absl::UnimplementedError("HC on the GPU: not a CVD energy");
        } else {
          const uint32_t n = static_cast<uint32_t>(problem.mesh->num_faces());
          MLCLUST_ASSIGN_OR_RETURN(
              HcLevelsGpu levels,
              HcLevelsGpu::Create(context, CvdFaceSums(energy, n), *problem.adjacency,
                                  options.ties_to_fewest_faces));
          MLCLUST_RETURN_IF_ERROR(SendFacesAsClusters(n, sink));
          MultilevelSummary summary;
          summary.levels = 1;
          // The CPU's LevelRecorder: keep's change, then gone's, per level.
          ::mlclust::detail::CompensatedSum energy_sum;
          energy_sum.Reset(0);
          uint32_t clusters = n;
          HcBatchGpu batch;
          LevelMoves moves;
          std::vector<uint32_t> to, from;
          // Small batches first: the first levels reach the sink early.
          uint32_t batch_steps = 64;
          while (clusters > options.min_clusters) {
            MLCLUST_RETURN_IF_ERROR(
                CheckCancelled(options.cancel, absl::StrCat("level ", summary.levels)));
            MLCLUST_RETURN_IF_ERROR(levels.Steps(options.min_clusters, batch_steps, batch));
            if (batch.steps.empty()) break;  // one cluster per component
            batch_steps = std::min(kHcMaxBatch, 2 * batch_steps);
            for (const HcStepGpu& step : batch.steps) {
              --clusters;
              energy_sum.Add(step.keep_change);
              energy_sum.Add(step.gone_change);
              moves.level = summary.levels;
              moves.cluster_count = clusters;
              moves.energy = energy_sum.value();
              to.assign(step.count, step.keep);
              from.assign(step.count, step.gone);
              moves.element =
                  std::span<const uint32_t>(batch.faces).subspan(step.first, step.count);
              moves.to_cluster = to;
              moves.from_cluster = from;
              MLCLUST_RETURN_IF_ERROR(sink.OnLevel(moves));
              summary.moves += step.count;
              ++summary.levels;
            }
          }
          summary.final_clusters = clusters;
          summary.final_energy = energy_sum.value();
          return summary;
        }
      });
}

}  // namespace mlclust::gpu
