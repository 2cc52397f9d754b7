// Model selection over the levels of a point clustering (dissertation section 6.6): which
// number of clusters the data supports, by the Bayesian Information Criterion (BIC) of a
// mixture of spherical Gaussians with one shared variance and hard assignments, the model of
// X-means (Pelleg & Moore 2000).
//
// With R points in M dimensions in K non-empty clusters of sizes R_n, and SSE the energy
// (sum of squared distances of the points to their cluster means):
//   s^2   = SSE / (M (R - K))                         the unbiased shared variance
//   log L = sum_n R_n ln(R_n / R) - (R M / 2) ln(2 pi s^2) - M (R - K) / 2
//   p     = (K - 1) + M K + 1                         mixing weights, means, variance
//   BIC   = log L - (p / 2) ln R                      larger is better
// This is the textbook derivation (the log-likelihood of the hard-assigned points at the
// maximum-likelihood parameters, with the unbiased variance); the formula printed in Pelleg
// & Moore's paper has known errors and is not used.
//
// The only term that depends on the individual sizes is sum_n R_n ln R_n, so a hierarchy,
// whose sizes change by a few elements per level, keeps it up to date in O(1) per moved
// element (SizeEntropyTracker; BicLevelRecorder does so for any driver's LevelSink).
#ifndef MLCLUST_CORE_HIERARCHY_MODEL_SELECTION_H_
#define MLCLUST_CORE_HIERARCHY_MODEL_SELECTION_H_

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "core/base/ids.h"
#include "core/hierarchy/hierarchy.h"

namespace mlclust {

// The BIC above. `cluster_sizes` holds R_n (zeros are skipped: K counts the non-empty
// clusters) and must sum to num_points = R >= 1; dims = M >= 1; `sse` >= 0.
//
// Degenerate levels score -infinity, so that the selection below never chooses one over a
// level with a defined BIC (and, where all are degenerate, takes the fewest clusters):
//  - K == R (every point alone): no degree of freedom is left to estimate the variance (the
//    first level of a bottom-up hierarchy);
//  - SSE <= 0 (every cluster a point mass, as duplicate points give; rounding in an
//    incrementally kept energy can leave a tiny negative value where the exact one is 0):
//    the variance estimate is 0 and the likelihood unbounded. Scoring these +infinity, the
//    limit, would let the few duplicate points of a real point cloud, which a bottom-up
//    hierarchy merges first at no cost, decide the choice.
// A tiny positive SSE (near-duplicates) still gives a very large BIC: the criterion has no
// scale to tell rounding from data.
double SphericalGaussianBic(std::span<const uint64_t> cluster_sizes, double sse,
                            uint64_t num_points, uint32_t dims);

// The same, given the sizes only through size_term = sum_n R_n ln R_n (natural logarithm)
// and the number of non-empty clusters K in [1, R].
double SphericalGaussianBicFromSizeTerm(double size_term, uint64_t clusters, double sse,
                                        uint64_t num_points, uint32_t dims);

// Keeps sum_n R_n ln R_n over clusters whose sizes change one at a time: O(1) per change,
// with compensated summation, so that millions of changes leave an error of a few units in
// the last place of the sum rather than one that grows with the number of changes.
class SizeEntropyTracker {
 public:
  SizeEntropyTracker() = default;

  // Sets the size of `cluster` (clusters not set yet have size 0; the tracker grows to hold
  // any id).
  void Set(uint32_t cluster, uint64_t size);
  // One element moves from cluster `from` (size >= 1) to `to`.
  void Move(uint32_t from, uint32_t to);

  uint64_t size(uint32_t cluster) const { return cluster < sizes_.size() ? sizes_[cluster] : 0; }
  uint64_t num_points() const { return num_points_; }        // sum of the sizes
  uint64_t num_clusters() const { return num_clusters_; }    // non-empty clusters
  double size_term() const { return sum_ + compensation_; }  // sum_n R_n ln R_n

 private:
  void Add(double term);

  std::vector<uint64_t> sizes_;
  uint64_t num_points_ = 0;
  uint64_t num_clusters_ = 0;
  double sum_ = 0;
  double compensation_ = 0;  // Neumaier's running correction to sum_
};

// One level of a clustering as the BIC needs it.
struct BicLevel {
  uint32_t clusters = 0;  // K: non-empty clusters
  double sse = 0;         // the energy: sum of squared distances to the cluster means
  double size_term = 0;   // sum_n R_n ln R_n (SizeEntropyTracker::size_term)
};

struct BicChoice {
  // The level of the largest BIC; where several levels tie, the one with the fewest clusters
  // (the simpler model), and among levels with equally many clusters the later one.
  size_t best_level = 0;
  uint32_t best_k = 0;
  // X-means' stopping rule ("stop at the first decrease", section 6.6), applied to the
  // levels ordered by their number of clusters from few to many, that is, for a hierarchy
  // that goes from n clusters down to 1, read from its last level back to its first: the
  // first level whose BIC is larger than that of the next level with more clusters. Where
  // the BIC never decreases, the level with the most clusters. Levels that share a number
  // of clusters take part through the one of the largest BIC (the later on ties); levels
  // whose BIC is -infinity (degenerate) take no part, unless all do, in which case this is
  // best_level, the level with the fewest clusters.
  //
  // Why from few to many: near the fine end of a bottom-up hierarchy (K close to R) the
  // variance rests on few degrees of freedom. On Gaussian blobs the BIC is high after the
  // first merge and falls level after level for hundreds of levels before it rises towards
  // the true K (tests/core/model_selection_test.cc), so read from that end the first
  // decrease comes at once and says nothing about the data. From the coarse end the BIC
  // rises while clusters the data support are split apart and falls at the first level
  // that splits one they do not.
  size_t first_decrease_level = 0;
  uint32_t first_decrease_k = 0;
  // Section 6.6's stopping rule as the text states it for ML ("stop merging when the BIC
  // starts to decrease", l. 2777, 2798): the levels read in their own order, a hierarchy's
  // from many clusters to few as it merges, and the level just before the first level whose
  // BIC is below it; where the BIC never falls, the last level. Degenerate levels
  // (-infinity) are skipped; where all are, this is best_level. Unlike first_decrease above
  // it reads the BIC where the variance rests on the fewest degrees of freedom, so from a
  // fine start it stops early (bench/pages/fidelity.md).
  size_t merging_first_decrease_level = 0;
  uint32_t merging_first_decrease_k = 0;
  std::vector<double> bic;  // per input level, in input order
};

// Computes the BIC of every level and chooses as BicChoice describes. The levels may come
// in any order (a hierarchy's, or a k-means sweep's); level indices in the result are
// positions in `levels`. INVALID_ARGUMENT naming the problem for no levels, num_points or
// dims 0, a level with 0 clusters or more clusters than points, or a NaN sse or size term.
absl::StatusOr<BicChoice> ChooseByBic(std::span<const BicLevel> levels, uint64_t num_points,
                                      uint32_t dims);

// The choice of ChooseByBic from given scores (one per level, larger is better; NaN is not
// allowed) and cluster counts of equal length >= 1.
BicChoice ChooseByScore(std::span<const uint32_t> cluster_counts, std::vector<double> scores);

// A LevelSink that records a BicLevel per level of a point hierarchy (level 0 from OnStart,
// then one per OnLevel): each element counts as one point, each level's energy is taken as
// its SSE (so the driver must run with an energy that is the SSE), and sizes are kept by a
// SizeEntropyTracker from the moves, O(1) per moved element. Pass levels() to ChooseByBic
// with num_points() and the points' dims.
class BicLevelRecorder : public LevelSink {
 public:
  // FAILED_PRECONDITION if called twice; INVALID_ARGUMENT for no labels, an invalid label,
  // or a cluster_count that is not the number of distinct labels.
  absl::Status OnStart(std::span<const ClusterId> labels, uint32_t cluster_count,
                       double energy) override;
  // FAILED_PRECONDITION before OnStart; INVALID_ARGUMENT where the spans differ in length, a
  // move leaves a cluster that is empty, or cluster_count is not the number of non-empty
  // clusters after the moves. Elements are not checked against their labels (HierarchyLog
  // does that); only sizes are kept.
  absl::Status OnLevel(const LevelMoves& level) override;

  const std::vector<BicLevel>& levels() const { return levels_; }
  uint64_t num_points() const { return sizes_.num_points(); }

 private:
  bool started_ = false;
  SizeEntropyTracker sizes_;
  std::vector<BicLevel> levels_;
};

}  // namespace mlclust

#endif  // MLCLUST_CORE_HIERARCHY_MODEL_SELECTION_H_
