#include "gpu/stages/gpu_working_set.h"

#include <algorithm>

#include "gpu/kernels/bb_decide.h"
#include "gpu/kernels/face_measures_gpu.h"
#include "gpu/kernels/hc_levels.h"
#include "gpu/kernels/kmeans_assign.h"
#include "gpu/kernels/ln_kmeans.h"
#include "gpu/kernels/pml_levels.h"
#include "gpu/kernels/points_levels.h"
#include "gpu/kernels/seed_growth.h"
#include "gpu/kernels/voxel_start.h"

namespace mlclust::gpu {
namespace {

// The mesh hierarchies' levels: HC's steps, or PML's levels (and ML's steps with BB), with
// the boundary pass where BB sweeps each level. Dual edges: at most 3 per face.
uint64_t MeshLevelsBound(const JobPlan& plan, uint64_t faces) {
  const uint64_t edges = 3 * faces;
  const MultilevelOptions& ml = plan.multilevel;
  if (ml.optimizer == MultilevelOptions::Optimizer::kNone && !ml.parallel) {
    return HcLevelsMemoryBound(faces, edges);
  }
  uint64_t bytes = PmlLevelsMemoryBound(faces, edges);
  if (ml.optimizer == MultilevelOptions::Optimizer::kBoundaryBased) {
    bytes += PmlBoundaryMemoryBound(faces, edges);
  }
  return bytes;
}

// The point hierarchies: the voxel start, then the levels (k at most m), with LN k-means'
// kernel where it optimises inside the levels.
uint64_t PointLevelsBound(const JobPlan& plan, uint64_t points, uint32_t dims) {
  uint64_t bytes =
      VoxelStartMemoryBound(points, dims) + PointLevelsMemoryBound(points, points, dims);
  if (plan.point_multilevel.optimizer == PointMultilevelOptions::Optimizer::kLnKmeans) {
    bytes += LnKmeansMemoryBound(points, dims,
                                 static_cast<uint32_t>(std::min<uint64_t>(points, UINT32_MAX)));
  }
  return bytes;
}

}  // namespace

uint64_t GpuWorkingSetBound(const GlContext& context, PlanStage stage, const JobPlan& plan,
                            const InputShape& input) {
  const uint64_t n = input.elements;
  if (plan.algorithm->input == InputKind::kMesh) {
    switch (stage) {
      case PlanStage::kMeasures:
        return ComputeFaceMeasuresGpuMemoryBound(context, n, input.vertices);
      case PlanStage::kSeed:
        return SeedGrowthMemoryBound(n);
      case PlanStage::kCluster:
        if (plan.algorithm->hierarchy) return MeshLevelsBound(plan, n);
        return BoundaryDecideMemoryBound(n, plan.clusters);  // BB's decide
    }
    return 0;
  }
  if (stage != PlanStage::kCluster) return 0;
  if (plan.algorithm->hierarchy) return PointLevelsBound(plan, n, input.dims);
  if (plan.algorithm->name == "kmeans")
    return KmeansAssignMemoryBound(n, input.dims, plan.clusters);
  return LnKmeansMemoryBound(n, input.dims, plan.clusters);  // LN k-means
}

}  // namespace mlclust::gpu
