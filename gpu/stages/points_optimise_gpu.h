// LN k-means inside the GPU's point levels (section 6.4.3: PML for data with LN k-means as
// minimizeEnergy): after each level's merges (PointLevelsGpu::MergeLevel), the rounds of
// the CPU's points PML, then the level's triplets and energy as the CPU's LevelRecorder
// makes them.
//
// The rounds are the CPU's own driver (core/cluster/detail/point_optimise.h: round 0 with
// the clusters next to the merged ones, the Hamerly bounds, bounded_drift, the apply pass)
// on a host mirror that is a detail::PointClusters over the points in the CPU's order (by
// starting cell), so its sums are the CPU's bit for bit. Only the assign stage differs:
//   - the GPU keeps the labels, counts, sums, centroids and neighbour table across levels
//     and runs every round's checks (LnKmeansKernel::AssignResident, pass "ln-kmeans
//     assign": the point against its own cluster, its cluster's neighbours and the
//     neighbours of the neighbour in its subspace, eq. 6.1, or round 0's merged clusters
//     that list its cluster), the merges and the neighbour refresh
//     (gpu/kernels/points_levels.h); one round trip per round: the check list up, the
//     targets and margins down;
//   - the driver applies each round's moves on the mirror in the checks' order; the changed
//     clusters and moved points go back in one scatter (pass "points update").
// The level's merges enter the mirror in the CPU engine's order (by merge cost, then
// pair), so the rounds' order is the CPU's: level 1 (merges and rounds) is the CPU's,
// triplets and energy. After level 1 the neighbour tables differ (points_multilevel_gpu.h):
// the hierarchies are alike, not identical; energies within 1% at every cluster count on
// the tests' sets and at 10^5 points (BENCHMARKS.md).
//
// Memory: on the GPU, LnKmeansMemoryBound besides PointLevelsMemoryBound; on the host the
// points once more in the CPU's order (4d bytes each), per point a label, an order entry
// each way, a member entry, a position, a stamp and a threshold (32 bytes), per cluster its
// sums, centroid, neighbours and drift (8(3d + 3) + 8d bytes).
#ifndef MLCLUST_GPU_STAGES_POINTS_OPTIMISE_GPU_H_
#define MLCLUST_GPU_STAGES_POINTS_OPTIMISE_GPU_H_

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "core/cluster/detail/point_optimise.h"
#include "core/cluster/point_clustering.h"
#include "core/hierarchy/hierarchy.h"
#include "core/hierarchy/level_recorder.h"
#include "core/points/points.h"
#include "gpu/context/gl_context.h"
#include "gpu/kernels/ln_kmeans.h"
#include "gpu/kernels/points_levels.h"

namespace mlclust::gpu {

// The host's clusters of the GPU's point levels, as the CPU's PointSpace keeps them: the
// points ordered by starting cluster (stably), their detail::PointClusters (the data's mean
// and every cluster's sums in the CPU's operation order), and the maps between the two
// orders. The start's neighbours are the caller's to set.
struct PointLevelsHost {
  PointSet sorted;
  std::vector<uint32_t> original;   // sorted's point -> the caller's
  std::vector<uint32_t> sorted_of;  // the caller's point -> sorted's
  std::unique_ptr<::mlclust::detail::PointClusters> clusters;
};

// `labels`: one per point of `points`, each < `clusters` (not checked).
std::unique_ptr<PointLevelsHost> MakePointLevelsHost(const PointSet& points,
                                                     std::span<const uint32_t> labels,
                                                     uint32_t clusters);

class PointLevelsOptimiser {
 public:
  // The mirror (`host`: the start PointLevelsGpu::Create uploaded, of `points`) and the
  // assign kernel (the points uploaded once more). `points` and `options` must outlive the
  // optimiser. INVALID_ARGUMENT for a host of other points; errors as
  // LnKmeansKernel::Create.
  static absl::StatusOr<PointLevelsOptimiser> Create(GlContext& context, const PointSet& points,
                                                     std::unique_ptr<PointLevelsHost> host,
                                                     const PointMultilevelOptions& options);

  // After levels.MergeLevel gave `merged` (true): its merges into the mirror, the LN
  // k-means rounds, and the level (its triplets in the order the recorder lists them)
  // reported to `sink` as level `index` with `clusters` clusters. The neighbours are not
  // refreshed (the caller's RefreshNeighbours). INTERNAL if the GPU's triplets do not
  // match the mirror; CANCELLED once options.cancel is set; the GPU's errors by pass; the
  // sink's.
  // With `read_neighbours` false the mirror's neighbour table is taken as the GPU's (HC's
  // and ML's steps keep it so with SetNeighbourRows).
  absl::Status Level(PointLevelsGpu& levels, const PointLevelGpu& merged, LevelSink& sink,
                     uint32_t index, uint32_t clusters, bool read_neighbours = true);

  // Cluster c's size in the mirror, and its points (the caller's ids, ascending) into `out`.
  uint64_t size(uint32_t c) const;
  void Members(uint32_t c, std::vector<uint32_t>& out) const;

  // The rows PointLevelsGpu::StepRefresh gave (n + 1 cluster ids, then their rows) into the
  // mirror's neighbour table. INTERNAL where they do not fit it.
  absl::Status SetNeighbourRows(std::span<const uint32_t> rows);

  uint64_t moves() const;
  // The clusters the last Level touched (merged or changed by a move), in the order the
  // CPU's LevelRecorder lists them (its affected()).
  std::span<const uint32_t> touched() const;

  PointLevelsOptimiser(PointLevelsOptimiser&&) noexcept;
  PointLevelsOptimiser& operator=(PointLevelsOptimiser&&) noexcept;
  ~PointLevelsOptimiser();

 private:
  // The host's state; on the heap, as the driver holds references into it.
  struct Mirror;
  PointLevelsOptimiser(std::unique_ptr<Mirror> mirror, LnKmeansKernel kernel);

  absl::Status ApplyMerges(const PointLevelGpu& merged);
  // The driver's assign stage: the slices' points to the GPU, their moves back.
  absl::Status Check(PointLevelsGpu& levels,
                     std::span<const ::mlclust::detail::PointOptimiseRounds::Slice> slices,
                     std::span<const ::mlclust::detail::PointOptimiseRounds::NextTo> next_to,
                     std::vector<::mlclust::detail::PointOptimiseRounds::Move>& moves);
  // A round's changes to the GPU (PointLevelsGpu::Update).
  absl::Status WriteBack(PointLevelsGpu& levels, std::span<const uint32_t> changed,
                         std::span<const ::mlclust::detail::PointOptimiseRounds::Move> moved);

  std::unique_ptr<Mirror> mirror_;
  LnKmeansKernel kernel_;
};

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_STAGES_POINTS_OPTIMISE_GPU_H_
