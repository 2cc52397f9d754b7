// The seam between the registry's run functions (core, which knows no GL) and stages
// implemented on a device: the server hands an implementation in RunContext::devices
// (gpu/stages/gl_device_stages.h implements it over the server's GL context), and a run
// function whose plan puts a stage on the GPU calls it instead of the CPU stage.
//
// Each method runs a whole driver with one stage on the device and every other stage the
// CPU's own (shared templates, so the rules cannot drift): the device policy
// (core/plan/device_policy.h) has already chosen the device at plan time, so a device
// error is the job's error (no fallback mid-job).
#ifndef MLCLUST_CORE_CLUSTER_DEVICE_STAGES_H_
#define MLCLUST_CORE_CLUSTER_DEVICE_STAGES_H_

#include <vector>

#include "absl/status/statusor.h"
#include "core/base/ids.h"
#include "core/cluster/kmeans.h"
#include "core/cluster/mesh_clustering.h"
#include "core/cluster/multilevel.h"
#include "core/cluster/point_clustering.h"
#include "core/energy/energies.h"
#include "core/hierarchy/hierarchy.h"
#include "core/mesh/face_measures.h"
#include "core/mesh/mesh.h"
#include "core/points/points.h"

namespace mlclust {

class DeviceStages {
 public:
  virtual ~DeviceStages() = default;

  // ComputeFaceMeasures (core/mesh/face_measures.h) on the device; same contract, plus the
  // device's errors.
  virtual absl::StatusOr<FaceMeasures> MeasureFaces(const TriangleMesh& mesh) = 0;

  // OptimizeBoundaryBased (mesh_clustering.h) with the decide stage on the device; same
  // contract, plus the device's errors (naming the pass).
  virtual absl::StatusOr<OptimizeResult> OptimizeBoundaryBased(
      const MeshProblem& problem, std::vector<ClusterId>& labels,
      const BoundaryBasedOptions& options) = 0;

  // RunLnKmeans (point_clustering.h) with the initial neighbours and the assign stage
  // on the device; same contract, plus the device's errors.
  virtual absl::StatusOr<LnKmeansResult> RunLnKmeans(const PointSet& points,
                                                     std::vector<ClusterId> labels,
                                                     const LnKmeansOptions& options) = 0;

  // RunLloyd (kmeans.h) with the assignment on the device; same contract, plus the
  // device's errors.
  virtual absl::StatusOr<KmeansResult> RunLloyd(const PointSet& points, std::vector<float> centres,
                                                const KmeansOptions& options) = 0;

  // RunMultilevel (multilevel.h) for PML with its levels on the device (merges only, or
  // with BB sweeps after each level as Alg. 5.7; the energies the device has:
  // gpu/stages/multilevel_gpu.h); same contract, plus the device's errors.
  virtual absl::StatusOr<MultilevelSummary> RunMultilevel(const MeshProblem& problem,
                                                          const MultilevelOptions& options,
                                                          LevelSink& sink) = 0;

  // RunMultilevel (multilevel.h) for HC (optimizer none, one merge per level) with its
  // steps on the device (gpu/stages/hierarchy_gpu.h); same contract, plus the device's
  // errors.
  // Also ML with optimizer bb (Alg. 5.6: one merge, then BB sweeps, per level;
  // gpu/stages/multilevel_gpu.h's RunMultilevelGpu).
  virtual absl::StatusOr<MultilevelSummary> RunHierarchy(const MeshProblem& problem,
                                                         const MultilevelOptions& options,
                                                         LevelSink& sink) = 0;

  // RunPointMultilevel (point_clustering.h) with the voxel start and the levels on the
  // device: PML's levels, or HC's and ML's steps (options.parallel false), merges only or
  // with LN k-means (gpu/stages/points_multilevel_gpu.h); same contract, plus the device's
  // errors.
  virtual absl::StatusOr<PointMultilevelSummary> RunPointMultilevel(
      const PointSet& points, const PointMultilevelOptions& options, LevelSink& sink) = 0;

  // SeedOptions::Growth::kRounds' growth on the device (section 5.2;
  // gpu/stages/seed_growth_gpu.h), as SeedOptions::device_rounds: the seed stage of BB,
  // EMLO and BB's preset patches sets it where the plan puts that stage on the device.
  virtual SeedOptions::DeviceGrowth RoundsGrowth() = 0;
};

}  // namespace mlclust

#endif  // MLCLUST_CORE_CLUSTER_DEVICE_STAGES_H_
