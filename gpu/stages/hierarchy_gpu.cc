#include "gpu/stages/hierarchy_gpu.h"

#include <algorithm>
#include <span>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"
#include "core/base/status_macros.h"
#include "gpu/kernels/hc_levels.h"
#include "gpu/stages/mesh_levels_gpu.h"

namespace mlclust::gpu {

absl::StatusOr<MultilevelSummary> RunHierarchyGpu(GlContext& context, const MeshProblem& problem,
                                                  const MultilevelOptions& options,
                                                  LevelSink& sink) {
  return WithCvdLevelsProblem(
      problem, options, "HC", HcGpuUnsupported(options, problem.energy.kind),
      [&](const CvdEnergy& energy) -> absl::StatusOr<MultilevelSummary> {
        const uint32_t n = static_cast<uint32_t>(problem.mesh->num_faces());
        MLCLUST_ASSIGN_OR_RETURN(
            HcLevelsGpu levels,
            HcLevelsGpu::Create(context, CvdFaceSums(energy, n), *problem.adjacency,
                                options.ties_to_fewest_faces));
        // The CPU's LevelRecorder: keep's change, then gone's, per level.
        MergeLevelReporter reporter(sink);
        MLCLUST_RETURN_IF_ERROR(reporter.Start(n));
        uint32_t clusters = n;
        HcBatchGpu batch;
        std::vector<uint32_t> to, from;
        // Small batches first: the first levels reach the sink early.
        uint32_t batch_steps = 64;
        while (clusters > options.min_clusters) {
          MLCLUST_RETURN_IF_ERROR(
              CheckCancelled(options.cancel, absl::StrCat("level ", reporter.next_level())));
          MLCLUST_RETURN_IF_ERROR(levels.Steps(options.min_clusters, batch_steps, batch));
          if (batch.steps.empty()) break;  // one cluster per component
          batch_steps = std::min(kHcMaxBatch, 2 * batch_steps);
          for (const HcStepGpu& step : batch.steps) {
            --clusters;
            reporter.AddChange(step.keep_change);
            reporter.AddChange(step.gone_change);
            to.assign(step.count, step.keep);
            from.assign(step.count, step.gone);
            MLCLUST_RETURN_IF_ERROR(reporter.Report(
                clusters, std::span<const uint32_t>(batch.faces).subspan(step.first, step.count),
                to, from));
          }
        }
        return reporter.Finish();
      });
}

}  // namespace mlclust::gpu
