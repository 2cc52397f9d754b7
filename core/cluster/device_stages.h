// The seam between the registry's run functions (core, which knows no GL) and stages
// implemented on a device: the server hands an implementation in RunContext::devices
// (gpu/stages/gl_device_stages.h implements it over the server's GL context), and a run
// function whose plan puts a stage on the GPU calls it instead of the CPU stage.
//
// Each method runs a whole driver with one stage on the device and every other stage the
// CPU's own (shared templates, so the rules cannot drift): the caller has already chosen
// the device at plan time, so a device error is the job's error (no fallback mid-job).
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
#include "core/points/points.h"

namespace mlclust {

// The energies whose BB decide stage has a GPU cost (gpu/kernels/bb_decide.h): the
// proxy-point energies (cvd, cvd-adaptive, mwcvd-*) and planar. The plan (registry.cc) and
// the GPU driver (gpu/stages/boundary_based_gpu.h) both read this one list.
inline bool HasGpuBoundaryDecide(MeshEnergyKind energy) {
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

// The most dimensions the GPU's point levels take (gpu/kernels/voxel_start.h's
// kVoxelStartMaxDims); with --device auto a point set with more runs on the CPU.
inline constexpr uint32_t kGpuPointMaxDims = 64;

class DeviceStages {
 public:
  virtual ~DeviceStages() = default;

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
  // gpu/stages/multilevel_gpu.h); same contract, plus the device's errors. UNIMPLEMENTED
  // where the device has none (the default).
  virtual absl::StatusOr<MultilevelSummary> RunMultilevel(const MeshProblem& problem,
                                                          const MultilevelOptions& options,
                                                          LevelSink& sink) {
    (void)problem;
    (void)options;
    (void)sink;
    return absl::UnimplementedError("PML levels on this device");
  }

  // RunMultilevel (multilevel.h) for HC (optimizer none, one merge per level) with its
  // steps on the device (gpu/stages/hierarchy_gpu.h); same contract, plus the device's
  // errors. UNIMPLEMENTED where the device has none (the default).
  // Also ML with optimizer bb (Alg. 5.6: one merge, then BB sweeps, per level;
  // gpu/stages/multilevel_gpu.h's RunMultilevelGpu).
  virtual absl::StatusOr<MultilevelSummary> RunHierarchy(const MeshProblem& problem,
                                                         const MultilevelOptions& options,
                                                         LevelSink& sink) {
    (void)problem;
    (void)options;
    (void)sink;
    return absl::UnimplementedError("HC levels on this device");
  }

  // RunPointMultilevel (point_clustering.h) with the voxel start and the levels on the
  // device: PML's levels, or HC's and ML's steps (options.parallel false), merges only or
  // with LN k-means (gpu/stages/points_multilevel_gpu.h); same contract, plus the device's
  // errors. UNIMPLEMENTED where the device has none (the default).
  virtual absl::StatusOr<PointMultilevelSummary> RunPointMultilevel(
      const PointSet& points, const PointMultilevelOptions& options, LevelSink& sink) {
    (void)points;
    (void)options;
    (void)sink;
    return absl::UnimplementedError("point levels on this device");
  }

  // SeedOptions::Growth::kRounds' growth on the device (section 5.2;
  // gpu/stages/seed_growth_gpu.h), as SeedOptions::device_rounds: the seed stage of BB,
  // EMLO and BB's preset patches sets it where the plan puts that stage on the device.
  // Empty where the device has none (the default).
  virtual SeedOptions::DeviceGrowth RoundsGrowth() { return {}; }
};

}  // namespace mlclust

#endif  // MLCLUST_CORE_CLUSTER_DEVICE_STAGES_H_
