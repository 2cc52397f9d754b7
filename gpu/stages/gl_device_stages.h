// The server's DeviceStages (core/cluster/device_stages.h) over its GL context: what the
// registry's run functions call for a stage that the job's plan puts on the GPU.
#ifndef MLCLUST_GPU_STAGES_GL_DEVICE_STAGES_H_
#define MLCLUST_GPU_STAGES_GL_DEVICE_STAGES_H_

#include <vector>

#include "core/cluster/device_stages.h"
#include "gpu/context/gl_context.h"

namespace mlclust::gpu {

// Borrows `context` (which must outlive it); use it on the context's thread only.
class GlDeviceStages : public DeviceStages {
 public:
  explicit GlDeviceStages(GlContext& context) : context_(context) {}

  absl::StatusOr<FaceMeasures> MeasureFaces(const TriangleMesh& mesh) override;
  absl::StatusOr<OptimizeResult> OptimizeBoundaryBased(
      const MeshProblem& problem, std::vector<ClusterId>& labels,
      const BoundaryBasedOptions& options) override;
  absl::StatusOr<LnKmeansResult> RunLnKmeans(const PointSet& points, std::vector<ClusterId> labels,
                                             const LnKmeansOptions& options) override;
  absl::StatusOr<KmeansResult> RunLloyd(const PointSet& points, std::vector<float> centres,
                                        const KmeansOptions& options) override;
  absl::StatusOr<MultilevelSummary> RunMultilevel(const MeshProblem& problem,
                                                  const MultilevelOptions& options,
                                                  LevelSink& sink) override;
  absl::StatusOr<MultilevelSummary> RunHierarchy(const MeshProblem& problem,
                                                 const MultilevelOptions& options,
                                                 LevelSink& sink) override;

  absl::StatusOr<PointMultilevelSummary> RunPointMultilevel(const PointSet& points,
                                                            const PointMultilevelOptions& options,
                                                            LevelSink& sink) override;

  SeedOptions::DeviceGrowth RoundsGrowth() override;

 private:
  GlContext& context_;
};

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_STAGES_GL_DEVICE_STAGES_H_
