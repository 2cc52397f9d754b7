// LN k-means (Alg. 6.1) on the GPU: the assign stage (each point against its own cluster,
// the cluster's local neighbours and the neighbours of the neighbour in its subspace, eq.
// 6.1) and the brute-force initial neighbours, as compute kernels. Apply and refresh stay
// the CPU's (core/cluster/detail/ln_kmeans_stages.h); gpu/stages/ln_kmeans_gpu.h drives
// them.
//
// Precision: fp64 distances from the float coordinates less the data's mean, with the
// CPU's operations in its order (`precise`: no fused multiply-add), so on a driver with
// IEEE fp64 (llvmpipe) the targets equal ChooseTargets'.
//
// Memory: the points stay on the GPU (4 d bytes per point), with labels, the points to
// check, their targets and margins (20 bytes per point), and per cluster its centroid, neighbours
// and count (8 d + 8 d + 4 bytes); LnKmeansMemoryBound. Each array must fit one storage
// buffer (RESOURCE_EXHAUSTED otherwise); d <= kLnKmeansMaxDims.
#ifndef MLCLUST_GPU_KERNELS_LN_KMEANS_H_
#define MLCLUST_GPU_KERNELS_LN_KMEANS_H_

#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "core/points/points.h"
#include "gpu/context/compute.h"
#include "gpu/context/gl_context.h"

namespace mlclust::gpu {

// The most dimensions the kernels take (the neighbour pass keeps 2d distances per
// invocation).
inline constexpr uint32_t kLnKmeansMaxDims = 64;

uint64_t LnKmeansMemoryBound(uint64_t num_points, uint32_t dims, uint32_t num_clusters);

// The clusters of another kernel, resident on the GPU, for LnKmeansKernel::AssignResident
// (the point levels' own buffers, gpu/kernels/points_levels.h): the labels (one uint per
// point), the centroids (k x d doubles, relative to the kernel's origin), the neighbours
// (k x 2d uints, 0xFFFFFFFF where none) and the counts (k uints).
struct LnKmeansResidentClusters {
  const StorageBuffer* labels = nullptr;
  const StorageBuffer* centroids = nullptr;
  const StorageBuffer* neighbours = nullptr;
  const StorageBuffer* counts = nullptr;
};

// Entries of AssignResident's check list compared with their own candidates only (the
// CPU's round 0 for the points next to a merged cluster, PointSpace::Optimise): entries
// from `full` on; entry full + e takes candidates[ranges[2e] .. ranges[2e + 1]) and moves to
// the nearest that is strictly nearer than its own centroid. Empty ranges: none.
struct LnKmeansOwnCandidates {
  size_t full = 0;
  std::span<const uint32_t> ranges;
  std::span<const uint32_t> candidates;
};

class LnKmeansKernel {
 public:
  // Uploads the points and the data's mean `origin` (d values) for k clusters. Returns
  // INVALID_ARGUMENT for d = 0 or > kLnKmeansMaxDims, origin.size() != d, or 2^31 points
  // or more; RESOURCE_EXHAUSTED / INTERNAL as the other kernels. Errors name the pass
  // "ln-kmeans assign".
  static absl::StatusOr<LnKmeansKernel> Create(GlContext& context, const PointSet& points,
                                               std::span<const double> origin,
                                               uint32_t num_clusters);

  // Uploads the clusters' state for the next passes: centroids (k x d, relative to the
  // origin), neighbours (k x 2d) and counts (k).
  absl::Status SetClusters(std::span<const double> centroids, std::span<const uint32_t> neighbours,
                           std::span<const uint32_t> counts);

  // The assign stage: target[r] for point check[r] (kNoCluster: stays), with the point
  // labels `labels` (one per point, each < k; not checked) and the clusters of the last
  // SetClusters. Every check[r] must be < the number of points (checked).
  absl::Status Assign(std::span<const uint32_t> labels, std::span<const uint32_t> check,
                      std::span<uint32_t> target);

  // The assign stage with the labels and the clusters already on the GPU: only `check`
  // goes up and the targets come back (same pass, same rule as Assign). The buffers must
  // hold a label for every point of this kernel and the clusters those labels and their
  // neighbours name (not checked on the GPU); every check[r] < the number of points.
  // With `margin` (check.size() values) also ChooseTargets' margins
  // (core/cluster/detail/ln_kmeans_stages.h; 0 for the entries of `own`). With `own`
  // (ranges for every entry from own.full on, each inside own.candidates), those entries
  // are compared with their own candidates only. The check buffer grows to hold the
  // ranges and candidates (4 bytes each).
  absl::Status AssignResident(const LnKmeansResidentClusters& clusters,
                              std::span<const uint32_t> check, std::span<uint32_t> target,
                              std::span<double> margin = {}, const LnKmeansOwnCandidates& own = {});

  // The local neighbours of every cluster (k x 2d) from the last SetClusters' centroids and
  // counts, by brute force (pass "ln-kmeans neighbours").
  absl::Status InitialNeighbours(std::span<uint32_t> neighbours);

 private:
  LnKmeansKernel(GlContext& context, uint32_t num_points, uint32_t dims, uint32_t num_clusters,
                 std::vector<StorageBuffer> buffers)
      : context_(&context),
        num_points_(num_points),
        dims_(dims),
        num_clusters_(num_clusters),
        buffers_(std::move(buffers)) {}

  // Assign's and AssignResident's checks and dispatch, with the clusters bound to the
  // assign shader's bindings 2 to 5.
  absl::Status DispatchAssign(const LnKmeansResidentClusters& clusters,
                              std::span<const uint32_t> check, std::span<uint32_t> target,
                              std::span<double> margin, const LnKmeansOwnCandidates& own);

  GlContext* context_;
  uint32_t num_points_;
  uint32_t dims_;
  uint32_t num_clusters_;
  // points, origin, labels, centroids, neighbours, counts, check, targets, margins: the
  // bindings.
  std::vector<StorageBuffer> buffers_;
};

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_KERNELS_LN_KMEANS_H_
