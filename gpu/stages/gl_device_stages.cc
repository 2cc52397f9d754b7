#include "gpu/stages/gl_device_stages.h"

#include <utility>

#include "absl/strings/str_cat.h"
#include "gpu/kernels/face_measures_gpu.h"
#include "gpu/stages/boundary_based_gpu.h"
#include "gpu/stages/hierarchy_gpu.h"
#include "gpu/stages/multilevel_gpu.h"
#include "gpu/stages/point_stages_gpu.h"
#include "gpu/stages/points_multilevel_gpu.h"
#include "gpu/stages/seed_growth_gpu.h"

namespace mlclust::gpu {

absl::StatusOr<FaceMeasures> GlDeviceStages::MeasureFaces(const TriangleMesh& mesh) {
  absl::StatusOr<FaceMeasures> measures = ComputeFaceMeasuresGpu(context_, mesh);
  if (!measures.ok()) {
    return absl::Status(measures.status().code(),
                        absl::StrCat("face measures on the GPU: ", measures.status().message()));
  }
  return measures;
}

absl::StatusOr<OptimizeResult> GlDeviceStages::OptimizeBoundaryBased(
    const MeshProblem& problem, std::vector<ClusterId>& labels,
    const BoundaryBasedOptions& options) {
  return OptimizeBoundaryBasedGpu(context_, problem, labels, options);
}

absl::StatusOr<LnKmeansResult> GlDeviceStages::RunLnKmeans(const PointSet& points,
                                                           std::vector<ClusterId> labels,
                                                           const LnKmeansOptions& options) {
  return RunLnKmeansGpu(context_, points, std::move(labels), options);
}

absl::StatusOr<KmeansResult> GlDeviceStages::RunLloyd(const PointSet& points,
                                                      std::vector<float> centres,
                                                      const KmeansOptions& options) {
  return RunLloydGpu(context_, points, std::move(centres), options);
}

absl::StatusOr<MultilevelSummary> GlDeviceStages::RunMultilevel(const MeshProblem& problem,
                                                                const MultilevelOptions& options,
                                                                LevelSink& sink) {
  return RunParallelMultilevelGpu(context_, problem, options, sink);
}

absl::StatusOr<MultilevelSummary> GlDeviceStages::RunHierarchy(const MeshProblem& problem,
                                                               const MultilevelOptions& options,
                                                               LevelSink& sink) {
  return RunMultilevelGpu(context_, problem, options, sink);  // HC, or ML with BB
}

absl::StatusOr<PointMultilevelSummary> GlDeviceStages::RunPointMultilevel(
    const PointSet& points, const PointMultilevelOptions& options, LevelSink& sink) {
  return options.parallel ? RunPointParallelMultilevelGpu(context_, points, options, sink)
                          : RunPointHierarchyGpu(context_, points, options, sink);  // HC or ML
}

SeedOptions::DeviceGrowth GlDeviceStages::RoundsGrowth() { return GpuRoundsGrowth(context_); }

}  // namespace mlclust::gpu
