// Bisecting k-means (dissertation Alg. 2.7, after Steinbach, Karypis & Kumar [SKK00]): a
// divisive hierarchy. The whole data set starts as one cluster; until there are k clusters,
// one cluster is picked and split in two by 2-means (core/cluster/kmeans.h), run `trials`
// times with different seeds, keeping the split of the smallest energy.
//
// The energy is the within-cluster sum of squares, as for k-means (eq. 6.4).
//
// Which cluster is split: the text says "in general the largest cluster"
// (kLargestSize); scikit-learn's BisectingKMeans splits the cluster of the largest energy by
// default (kLargestEnergy, "biggest_inertia"), which is ours to offer beside it.
//
// The result is a hierarchy: the split order is recorded, so the levels from k clusters
// back to 1 (undoing the splits in reverse order) can be sent as any hierarchy is
// (EmitBisectingLevels).
#ifndef MLCLUST_CORE_CLUSTER_BISECTING_KMEANS_H_
#define MLCLUST_CORE_CLUSTER_BISECTING_KMEANS_H_

#include <atomic>
#include <cstdint>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "core/base/ids.h"
#include "core/cluster/kmeans.h"
#include "core/hierarchy/hierarchy.h"
#include "core/points/points.h"

namespace mlclust {

// KmeansRunOptions: the settings of each 2-means run. Its seeding defaults to two random
// points (scikit-learn's default for BisectingKMeans) instead of k-means++; `seed` seeds the
// trials' seeds; `threads` serves the 2-means runs on clusters of at least 65,536 points
// (smaller ones run on one thread), and the result does not depend on it; `cancel` is
// checked before each split and within each 2-means run.
struct BisectingKmeansOptions : KmeansRunOptions {
  BisectingKmeansOptions() { init = Init::kRandom; }

  // k: in [1, points].
  uint32_t clusters = 0;
  enum class SplitChoice {
    // The cluster with the most points (Alg. 2.7's "largest cluster"); ties to the smaller
    // cluster id.
    kLargestSize,
    // The cluster with the largest energy (scikit-learn's default); ties to the smaller id.
    kLargestEnergy,
  };
  SplitChoice split = SplitChoice::kLargestSize;
  // L in Alg. 2.7: 2-means runs per bisecting step (seeds seed, seed + 1, ...); the split of
  // the smallest energy is kept. At least 1. 1 is scikit-learn's default (n_init=1).
  uint32_t trials = 1;
};

struct BisectingSplit {
  ClusterId parent;            // the cluster that was split; keeps the first half
  ClusterId child;             // the new cluster (id = number of clusters before the split)
  double energy = 0;           // the total energy after this split
  uint64_t parent_points = 0;  // points of `parent` after the split
  uint64_t child_points = 0;
};

struct BisectingKmeansResult {
  // One cluster per point, 0..k-1; every cluster non-empty.
  std::vector<ClusterId> labels;
  // k x d, row-major: the mean of each cluster (rounded to float).
  std::vector<float> centres;
  // The energy of `labels` (sum of squared distances to the cluster means, in double).
  double inertia = 0;
  // The energy of the single cluster before any split.
  double initial_energy = 0;
  // In order; splits[j] made cluster j + 1. k - 1 entries.
  std::vector<BisectingSplit> splits;
};

// Runs Alg. 2.7 on `points`. A cluster of one point is never split; where every cluster
// left has one point, k = m has been reached. Splitting a cluster of equal points gives
// two clusters of energy 0 (the 2-means moves a point into the empty half).
//
// Cost: each split runs `trials` 2-means runs over the points of the cluster split (a copy
// of them), so the total is about trials x m x depth of the tree x iterations distance
// terms, O(m log k) for balanced splits.
//
// Errors: ValidatePoints' INVALID_ARGUMENT; INVALID_ARGUMENT naming 'clusters' (k < 1 or
// k > m), 'trials' (0), 'max_iterations' (0), 'tolerance' (negative or NaN) or 'threads'
// (< 0); RunKmeans' errors; CANCELLED where options.cancel was set.
absl::StatusOr<BisectingKmeansResult> RunBisectingKmeans(const PointSet& points,
                                                         const BisectingKmeansOptions& options);

// The levels of a bisecting result as a bottom-up hierarchy, the way every hierarchy in the
// product is sent: level 0 is `result.labels` (k clusters, its energy), then one level per
// split undone, last split first: the points of the split's child go back to its parent
// (triplets (point, parent, child)), with the energy before that split; the last level has
// one cluster. O(m x depth of the tree). Errors are the sink's.
absl::Status EmitBisectingLevels(const BisectingKmeansResult& result, LevelSink& sink);

}  // namespace mlclust

#endif  // MLCLUST_CORE_CLUSTER_BISECTING_KMEANS_H_
