// LN k-means inside the GPU's point levels (section 6.4.3: PML for data with LN k-means as
// minimizeEnergy): after each level's merges (PointLevelsGpu::MergeLevel), the rounds the
// CPU's points PML runs (PointSpace::Optimise in core/cluster/point_clustering.cc), then
// the level's triplets and energy as the CPU's LevelRecorder makes them.
//
// Who does what:
//   - the GPU keeps the labels, counts, sums, centroids and neighbour table across levels
//     and runs every round's assign stage (LnKmeansKernel::AssignResident, pass
//     "ln-kmeans assign": the point against its own cluster, its cluster's neighbours and
//     the neighbours of the neighbour in its subspace, eq. 6.1), the merges and the
//     neighbour refresh (gpu/kernels/points_levels.h);
//   - the host keeps a mirror of the counts, sums, centroids, labels and member lists and
//     applies each round's moves one after the other, as the CPU does (a cluster's last
//     point stays; sums in the CPU's operation order); the changed clusters and moved
//     points go back in one scatter (pass "points update"). One round trip per round:
//     the check list up, the targets down.
//
// The rounds, as the CPU's: round 0 checks the points of the level's merged clusters and
// of the clusters next to them (the pre-refresh neighbours of a merged one); each later
// round the points of the clusters the previous round changed that are not checked yet in
// this level or whose margin their centroids' drift may have used up (the CPU's Hamerly
// bound: the GPU's assign returns each point's margin, the host keeps the thresholds and
// drifts as PointSpace does), until none changes or options.optimise_rounds have run.
// Round 0 compares the points next to a merged cluster with the merged clusters that list
// their cluster only, as the CPU does (LnKmeansOwnCandidates). Level 1 (merges and
// rounds) came out identical to the CPU's, triplets and energy, on every test set and at
// 10^5 points; that is not guaranteed, as a round's moves are applied in the GPU's order
// (merged clusters in the order of their first point), not the CPU engine's. After level 1
// the neighbour tables differ (points_multilevel_gpu.h): the hierarchies are alike, not
// identical; energies within 1% at every cluster count on the tests' sets and at 10^5
// points (BENCHMARKS.md).
//
// Memory: on the GPU, the points (4d bytes each) and per point a check entry, a target and
// a margin (16 bytes) besides PointLevelsGpu's; on the host, per point a label, a
// position, a member entry, a stamp and a threshold (24 bytes), per cluster its sums,
// centroid and drift (8(2d + 2) bytes) and the level's neighbour table (8d bytes).
#ifndef MLCLUST_GPU_STAGES_POINTS_OPTIMISE_GPU_H_
#define MLCLUST_GPU_STAGES_POINTS_OPTIMISE_GPU_H_

#include <atomic>
#include <cstdint>
#include <span>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "core/cluster/point_clustering.h"
#include "core/hierarchy/hierarchy.h"
#include "core/hierarchy/level_recorder.h"
#include "core/points/points.h"
#include "gpu/context/gl_context.h"
#include "gpu/kernels/ln_kmeans.h"
#include "gpu/kernels/points_levels.h"

namespace mlclust::gpu {

// The start's clusters as the optimiser takes them (the host mirror's first state, the
// same values PointLevelsGpu::Create uploaded).
struct PointOptimiserStart {
  std::vector<double> origin;     // d: the data's mean the sums are relative to
  std::vector<uint32_t> labels;   // per point, in the caller's order
  std::vector<uint32_t> counts;   // k
  std::vector<double> sums;       // k x (d + 1)
  std::vector<double> centroids;  // k x d
  double energy = 0;              // level 0's
};

class PointLevelsOptimiser {
 public:
  // The assign kernel (the points uploaded once more) and the mirror. `points` must
  // outlive the optimiser. Errors as LnKmeansKernel::Create.
  static absl::StatusOr<PointLevelsOptimiser> Create(GlContext& context, const PointSet& points,
                                                     PointOptimiserStart start, uint32_t rounds,
                                                     const std::atomic<bool>* cancel);

  // After levels.MergeLevel gave `merged` (true): its merges into the mirror, the LN
  // k-means rounds, and the level (its triplets in the order the recorder lists them)
  // reported to `sink` as level `index` with `clusters` clusters. The neighbours are not
  // refreshed (the caller's RefreshNeighbours). INTERNAL if the GPU's triplets do not
  // match the mirror; CANCELLED between rounds; the GPU's errors by pass; the sink's.
  absl::Status Level(PointLevelsGpu& levels, const PointLevelGpu& merged, LevelSink& sink,
                     uint32_t index, uint32_t clusters);

  uint64_t moves() const { return recorder_.moves(); }

 private:
  PointLevelsOptimiser(const PointSet& points, PointOptimiserStart start, uint32_t rounds,
                       const std::atomic<bool>* cancel, LnKmeansKernel kernel);

  double Energy(uint32_t c) const;
  void UpdateCentroid(uint32_t c);
  // PointClusters::Add: point i's coordinates less the origin into (+1) or out of (-1) c.
  void Add(uint32_t c, uint32_t i, int sign);
  absl::Status ApplyMerges(const PointLevelGpu& merged);
  // One round's moves, applied in `check` order; fills changed_ and moved_ and adds the
  // changed clusters' centroid moves to their drift.
  void ApplyMoves();
  // How far cluster c's centroid has moved in this level (a sum of steps), and the largest
  // such drift among its neighbours and theirs (PointSpace's NeighbourhoodDrift).
  double Drift(uint32_t c) const { return drift_epoch_[c] == epoch_ ? drift_[c] : 0.0; }
  double NeighbourhoodDrift(uint32_t c) const;
  // A later round's points to check, in region order (PointSpace::SelectForCheck).
  void SelectForCheck(std::span<const uint32_t> region);
  absl::Status WriteBack(PointLevelsGpu& levels);

  const PointSet* points_;
  uint32_t d_;
  PointOptimiserStart state_;
  uint32_t rounds_;
  const std::atomic<bool>* cancel_;
  LnKmeansKernel kernel_;
  std::vector<std::vector<uint32_t>> members_;
  std::vector<uint32_t> position_;
  std::vector<uint8_t> mark_;
  LevelRecorder recorder_;
  std::vector<uint32_t> merged_, check_, target_, changed_, moved_;
  // The level's neighbour table (before its refresh) and the Hamerly bounds: per point the
  // level of its last check and the drift it can absorb, per cluster its drift in this
  // level and the level that last had it in a round's region.
  std::vector<uint32_t> table_;
  uint32_t epoch_ = 0;
  std::vector<uint32_t> stamp_, drift_epoch_, region_epoch_;
  std::vector<double> threshold_, drift_, margin_, old_centroids_;
};

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_STAGES_POINTS_OPTIMISE_GPU_H_
