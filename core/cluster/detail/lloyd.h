// Lloyd's iterations (RunLloyd, core/cluster/kmeans.h) with the assignment step as a stage:
// the one loop that the CPU (RunKmeans, RunLloyd) and a device (RunLloydGpu,
// gpu/stages/point_stages_gpu.h) both run, so that the rules after the assignment (a point
// leaves its cluster only where that lowers its distance in double, empty clusters take the
// farthest points, the centres, the energy, the stop) cannot drift. Internal to core/cluster
// and its device stages.
#ifndef MLCLUST_CORE_CLUSTER_DETAIL_LLOYD_H_
#define MLCLUST_CORE_CLUSTER_DETAIL_LLOYD_H_

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "core/cluster/kmeans.h"
#include "core/points/points.h"

namespace mlclust::detail {

// The assignment step: every point's nearest centre (ties to the smaller centre id). Its
// answer is a proposal; the loop keeps a point in its cluster where the proposed centre is
// not nearer in double.
class LloydAssignStage {
 public:
  virtual ~LloydAssignStage() = default;
  // Once per iteration, before Nearest: the current centres (k x d, row-major, in double;
  // k stays the same for a run). A device runs its whole assignment here.
  virtual absl::Status SetCentres(std::span<const double> centres) = 0;
  // The nearest centres of points begin..end-1 (one block of the loop's, at most 1024
  // points): either written to `scratch` (room for end - begin) and returned, or a pointer
  // to the stage's own answers. Called from several threads at once for different blocks.
  virtual const uint32_t* Nearest(size_t begin, size_t end, uint32_t* scratch) const = 0;
};

// RunLloyd with `assign` as its assignment step: the same checks, errors and contract, plus
// the stage's errors. RunLloyd is this with the CPU's vectorised float kernel.
absl::StatusOr<KmeansResult> RunLloydWithAssign(const PointSet& points, std::vector<float> centres,
                                                const KmeansOptions& options,
                                                LloydAssignStage& assign);

}  // namespace mlclust::detail

#endif  // MLCLUST_CORE_CLUSTER_DETAIL_LLOYD_H_
