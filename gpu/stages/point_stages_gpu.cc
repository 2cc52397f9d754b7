#include "gpu/stages/point_stages_gpu.h"

#include <optional>
#include <span>
#include <utility>
#include <vector>

#include "core/base/cancel.h"
#include "core/base/renumber.h"
#include "core/base/status_macros.h"
#include "core/cluster/detail/lloyd.h"
#include "core/cluster/detail/ln_kmeans_stages.h"
#include "core/cluster/detail/point_levels_checks.h"
#include "gpu/kernels/kmeans_assign.h"
#include "gpu/kernels/ln_kmeans.h"

namespace mlclust::gpu {
namespace {

// The counts of a PointClusters as the kernel reads them (a count is below 2^31 points).
void Counts(const mlclust::detail::PointClusters& clusters, std::vector<uint32_t>& counts) {
  counts.resize(clusters.capacity());
  for (uint32_t c = 0; c < clusters.capacity(); ++c) {
    counts[c] = static_cast<uint32_t>(clusters.count(c));
  }
}

// Lloyd's assignment step on the GPU: the whole assignment in SetCentres (pass "kmeans
// assign", fp32), its answers handed out block by block.
class GpuLloydAssign final : public mlclust::detail::LloydAssignStage {
 public:
  GpuLloydAssign(GlContext& context, const PointSet& points)
      : context_(context), points_(points), nearest_(points.num_points()) {}

  absl::Status SetCentres(std::span<const double> centres) override {
    if (!kernel_.has_value()) {
      const auto k = static_cast<uint32_t>(centres.size() / points_.dims);
      MLCLUST_ASSIGN_OR_RETURN(KmeansAssignKernel kernel,
                               KmeansAssignKernel::Create(context_, points_, k));
      kernel_.emplace(std::move(kernel));
    }
    upload_.assign(centres.begin(), centres.end());
    return kernel_->Assign(upload_, nearest_);
  }

  const uint32_t* Nearest(size_t begin, size_t end, uint32_t* scratch) const override {
    (void)end;
    (void)scratch;
    return nearest_.data() + begin;
  }

 private:
  GlContext& context_;
  const PointSet& points_;
  std::optional<KmeansAssignKernel> kernel_;
  std::vector<float> upload_;
  std::vector<uint32_t> nearest_;
};

}  // namespace

absl::StatusOr<LnKmeansResult> RunLnKmeansGpu(GlContext& context, const PointSet& points,
                                              std::vector<ClusterId> labels,
                                              const LnKmeansOptions& options) {
  MLCLUST_RETURN_IF_ERROR(mlclust::detail::CheckLnKmeansArguments(points, labels.size()));
  const size_t m = points.num_points();
  // Compact ids by first appearance, as RunLnKmeans does; the caller's come back.
  const Renumbering<ClusterId> compact =
      RenumberByFirstAppearance(std::span<const ClusterId>(labels));
  const uint32_t k = compact.size();
  mlclust::detail::PointClusters clusters(points, compact.dense, k);
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "LN k-means set-up"));
  MLCLUST_ASSIGN_OR_RETURN(LnKmeansKernel kernel,
                           LnKmeansKernel::Create(context, points, clusters.origin(), k));
  std::vector<uint32_t> counts;
  Counts(clusters, counts);
  MLCLUST_RETURN_IF_ERROR(
      kernel.SetClusters(clusters.centroids(), clusters.neighbour_table(), counts));
  MLCLUST_RETURN_IF_ERROR(kernel.InitialNeighbours(clusters.neighbour_table()));
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "LN k-means neighbours"));
  LnKmeansResult result;
  MLCLUST_RETURN_IF_ERROR(mlclust::detail::RunLnKmeansIterations(
      clusters, options, result,
      [&](const mlclust::detail::PointClusters& state, std::span<const uint32_t> check,
          std::span<uint32_t> target) -> absl::Status {
        Counts(state, counts);
        MLCLUST_RETURN_IF_ERROR(
            kernel.SetClusters(state.centroids(), state.neighbour_table(), counts));
        return kernel.Assign(state.labels(), check, target);
      }));
  result.labels.resize(m);
  for (size_t i = 0; i < m; ++i) result.labels[i] = compact.original[clusters.label(i)];
  return result;
}

absl::StatusOr<KmeansResult> RunLloydGpu(GlContext& context, const PointSet& points,
                                         std::vector<float> centres, const KmeansOptions& options) {
  GpuLloydAssign assign(context, points);
  return mlclust::detail::RunLloydWithAssign(points, std::move(centres), options, assign);
}

}  // namespace mlclust::gpu
