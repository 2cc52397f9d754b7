// Point clustering (chapter 6): local neighbours, LN k-means, the voxel-grid start and the
// multilevel engine (ML, PML, HC) for points.
//
// Energy (eq. 6.5): the within-cluster sum of squares, E = sum_i sum_{x in C_i} |x - c_i|^2
// with c_i the cluster mean. Merge cost E(A u B) - E(A) - E(B) = (n_a n_b / (n_a + n_b))
// |c_a - c_b|^2 (Ward's criterion).
//
// Local neighbours (section 6.1): instead of a mesh's adjacency, each cluster keeps up to
// 2d neighbours, the closest cluster (by centroid) in each half-axis subspace around its
// centroid (eq. 6.1). After any change they are refreshed from the second-order
// neighbours (the neighbours' neighbours), so no step looks at all clusters.
//
// ML / PML / HC for points run on the mesh's multilevel engine
// (core/cluster/detail/multilevel_engine.h) with the local neighbours as the neighbourhood.
#ifndef MLCLUST_CORE_CLUSTER_POINT_CLUSTERING_H_
#define MLCLUST_CORE_CLUSTER_POINT_CLUSTERING_H_

#include <atomic>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "absl/status/statusor.h"
#include "core/base/ids.h"
#include "core/cluster/detail/pml_pairs.h"
#include "core/hierarchy/hierarchy.h"
#include "core/points/points.h"

namespace mlclust {

// Eq. 6.1 as we read it: the half-axis subspace of `to` seen from `from`: the axis j on
// which they differ most, and its sign: 2j for to_j > from_j, 2j + 1 otherwise. Ties go to
// the lower axis. In [0, 2d).
uint32_t SubspaceIndex(std::span<const double> from, std::span<const double> to);

// The voxel-grid start (section 6.2): the bounding box cut into `grid` cells per
// dimension (0: chosen as PointMultilevelOptions::grid says); each occupied cell is a
// cluster (only occupied cells exist: a hash of cells, so a^d never matters);
// face-sharing occupied cells are the first local neighbours. Labels numbered 0..k-1 in
// order of first occupied point. INVALID_ARGUMENT for a grid over 2^20; CANCELLED once
// `cancel` is set (checked every 65,536 points).
struct VoxelStart {
  std::vector<ClusterId> labels;
  uint32_t clusters = 0;
};
absl::StatusOr<VoxelStart> VoxelGridStart(const PointSet& points, uint32_t grid,
                                          const std::atomic<bool>* cancel = nullptr);

struct LnKmeansOptions {
  uint32_t max_iterations = 300;
  int threads = 0;  // 0: all cores
  // Called after each iteration with the number of points that moved and the energy.
  std::function<void(uint32_t iteration, uint64_t moved, double energy)> on_iteration;
  // Set from any thread to stop: checked during the start (every 65,536 points or 16
  // clusters) and after each stage of an iteration; the call then returns CANCELLED.
  const std::atomic<bool>* cancel = nullptr;
};

struct LnKmeansResult {
  std::vector<ClusterId> labels;
  double initial_energy = 0;
  double energy = 0;
  uint32_t iterations = 0;
  uint64_t moves = 0;
  bool converged = false;
};

// LN k-means (Alg. 6.1) from `labels` (any ids; kept): all points in parallel, each checked
// against its own cluster, its cluster's local neighbours and the neighbours of the
// neighbour in the point's own subspace (at most 4d - 1 other clusters), until no point
// moves. A cluster's last point never leaves, so k stays. The energy never increases.
absl::StatusOr<LnKmeansResult> RunLnKmeans(const PointSet& points, std::vector<ClusterId> labels,
                                           const LnKmeansOptions& options = {});

// LN k-means from the voxel-grid start (section 6.2): one cluster per occupied cell
// (`grid` cells per dimension; 0 chooses as PointMultilevelOptions::grid says), the
// face-sharing occupied cells as first neighbours. Labels 0..k-1, k the occupied cells.
absl::StatusOr<LnKmeansResult> RunLnKmeansFromGrid(const PointSet& points, uint32_t grid,
                                                   const LnKmeansOptions& options = {});

// k distinct points, uniformly at random (reproducible with `seed`), as k x d centres.
// INVALID_ARGUMENT naming 'clusters' for k < 1 or k > m.
absl::StatusOr<std::vector<float>> RandomPointCentres(const PointSet& points, uint32_t k,
                                                      uint64_t seed);

// Exactly k starting clusters: each point joins its nearest centre, the centres being
// greedy k-means++ (core/kmeans.h) or k distinct random points, reproducible with `seed`.
absl::StatusOr<std::vector<ClusterId>> SeedPointClusters(const PointSet& points, uint32_t k,
                                                         bool kmeans_plus_plus, uint64_t seed,
                                                         int threads = 0);

struct PointMultilevelOptions {
  enum class Optimizer { kLnKmeans, kNone };
  Optimizer optimizer = Optimizer::kLnKmeans;
  bool parallel = false;   // PML: mutual optimal dual edges collapsed together per level
  uint32_t pml_until = 0;  // then ML below this many clusters
  // Which mutual pairs a PML level collapses (PmlPairRule, core/cluster/detail/pml_pairs.h).
  // kAll: every one (Alg. 5.3). kCheaperHalf (default): those that cost at most the
  // median mutual pair of the level; near the data's own scale the mutual pairs mix
  // pieces of one cluster with whole clusters, and collapsing all of them merges whole
  // clusters while pieces remain (on 100 blobs of 1,000 points: 1.5x ML's energy at 86
  // clusters with kAll, within 7% of ML at every level with kCheaperHalf, in about half
  // ML's time).
  using PmlPairs = PmlPairRule;
  PmlPairRule pml_pairs = PmlPairRule::kCheaperHalf;
  uint32_t min_clusters = 1;
  // LN k-means rounds after each level's merges (the first checks every point of the merged
  // clusters and the points of their neighbours against them; each later one the points of
  // the clusters the previous round changed that are not checked yet in this level or that
  // their centroids' moves may have changed, until none changes). 8 (default): as since the
  // first version. Ours, for measuring: fewer rounds cost less (the later rounds are most of
  // ML's time on points) and raise the energy by an amount that depends on the data (2
  // rounds: +0.5% to +8% on average; BENCHMARKS.md "ML for points: per-point margins").
  // 1 to 64 (INVALID_ARGUMENT otherwise).
  uint32_t optimise_rounds = 8;
  // Ours (0, default: off, the rounds as above): in the later rounds, a changed cluster whose
  // centroid and neighbourhood moved in this level (the drift the thresholds are compared
  // with) by less than this share of the cluster's RMS radius sqrt(E_c / n_c) keeps its
  // points that are not checked yet in this level unchecked (those checked are compared
  // with their thresholds as always). A large cluster that gains or loses a few points then
  // costs nothing instead of a check of all its points; the energy cost is measured in
  // BENCHMARKS.md ("ML for points: bounded_drift"). 0 to 1 (INVALID_ARGUMENT otherwise).
  double bounded_drift = 0;
  // Voxels per dimension of the start. 0: aiming at eight points per cell: (m / 8)^(1/d)
  // per dimension where that is at least 4; in higher dimensions the widest cells are
  // halved, axis by axis, until about m / 8 cells are occupied (so a 64-D set still starts
  // from many clusters, not from one).
  uint32_t grid = 0;
  // Level 0. kGrid (default, ours): the voxel clusters as they are. kOptimisedGrid (the
  // text's, Fig. 6.5 / 6.8): LN k-means (Alg. 6.1, at most 300 iterations) on the voxel
  // clusters first, as RunLnKmeansFromGrid, and the hierarchy from its result (clusters that
  // LN k-means emptied dropped).
  enum class Start { kGrid, kOptimisedGrid };
  Start start = Start::kGrid;
  int threads = 0;
  std::function<void(size_t level, std::span<const uint32_t> labels)> inspect_level;
  // Set from any thread to stop: checked during the start (every 65,536 points), after
  // every level and between LN k-means rounds; the run then returns CANCELLED.
  const std::atomic<bool>* cancel = nullptr;
};

struct PointMultilevelSummary {
  uint32_t levels = 0;
  uint32_t start_clusters = 0;
  uint32_t final_clusters = 0;
  uint64_t moves = 0;
  uint32_t grid = 0;  // the largest number of cells on an axis of the start
};

// ML / PML / HC for points from the voxel-grid start; every level to `sink` (level 0: the
// voxel clusters). ODEs come from the local neighbours (section 6.3); LN k-means is the
// optimiser, run around the merged clusters. INVALID_ARGUMENT for out-of-range options;
// CANCELLED once `options.cancel` is set; the sink's status if it stops the run.
absl::StatusOr<PointMultilevelSummary> RunPointMultilevel(const PointSet& points,
                                                          const PointMultilevelOptions& options,
                                                          LevelSink& sink);

// The energy of a labelling, by its definition (two passes: means, then distances).
double PointEnergy(const PointSet& points, std::span<const ClusterId> labels);

}  // namespace mlclust

#endif  // MLCLUST_CORE_CLUSTER_POINT_CLUSTERING_H_
