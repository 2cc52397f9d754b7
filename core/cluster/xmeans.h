// X-means (dissertation Alg. 2.5, after Pelleg & Moore [PM00]): k-means that estimates the
// number of clusters in [k_min, k_max] with the Bayesian Information Criterion.
//
//   1  k-means with k_min clusters (k-means++ seeds, core/cluster/kmeans.h)
//   2  repeat while k < k_max and some split was applied:
//   3    split every cluster virtually in two by 2-means on its own points
//   4    keep a split where the BIC of the two halves, computed on the cluster's points
//        alone, exceeds the BIC of the cluster as one (PM00's local test; footnote 4
//        of the text's section 2.2.2), best gain first while k stays <= k_max
//   5    k-means (Lloyd) over all points from the centres of the kept halves and the
//        clusters left whole (PM00's Improve-Params)
//
// The BIC is that of core/hierarchy/model_selection.h (spherical Gaussians with one shared
// variance, hard assignments), for the local tests and for the whole model. As PM00 do, the
// result is the model of the largest BIC over all rounds (with the rounds recorded), which
// on data with that many clusters is the last round.
#ifndef MLCLUST_CORE_CLUSTER_XMEANS_H_
#define MLCLUST_CORE_CLUSTER_XMEANS_H_

#include <atomic>
#include <cstdint>
#include <vector>

#include "absl/status/statusor.h"
#include "core/base/ids.h"
#include "core/cluster/kmeans.h"
#include "core/points/points.h"

namespace mlclust {

// KmeansRunOptions: the settings of the first k-means and of every 2-means and k-means run
// after it (k-means++ seeding by default); `seed` seeds their seeds; `threads` serves
// k-means over all points and 2-means on clusters of at least 65,536 points (smaller ones
// run on one thread), and the result does not depend on it; `cancel` is checked between the
// virtual splits, between rounds and within each k-means run.
struct XmeansOptions : KmeansRunOptions {
  // k_min in [1, points]: the clusters of the first k-means.
  uint32_t min_clusters = 1;
  // k_max in [k_min, points]; 0: the number of points. No round goes beyond it.
  uint32_t max_clusters = 0;
  // 2-means runs per virtual split (seeded differently); the halves of least energy are
  // tested. At least 1.
  uint32_t split_trials = 1;
};

struct XmeansRound {
  uint32_t clusters = 0;  // k after the round's k-means
  double inertia = 0;     // its energy (sum of squared distances to the cluster means)
  double bic = 0;         // its BIC over all points
  uint32_t splits = 0;    // splits the round applied (0 for the first k-means)
};

struct XmeansResult {
  // The model of the largest BIC over the rounds: one cluster per point, 0..k-1, every
  // cluster non-empty; its centres k x d (rounded to float), energy and BIC.
  std::vector<ClusterId> labels;
  std::vector<float> centres;
  double inertia = 0;
  double bic = 0;
  uint32_t clusters = 0;
  // Every round in order; rounds[chosen_round] is the result above.
  std::vector<XmeansRound> rounds;
  size_t chosen_round = 0;
  // Why the search ended: no virtual split raised the local BIC, or k reached k_max.
  bool stopped_at_max = false;
};

// Runs Alg. 2.5 on `points`. A cluster of fewer than three points is never split (two
// halves of one and two points leave no degree of freedom for the variance).
//
// Cost per round: 2-means over every cluster's points (split_trials x m points in all) and
// one k-means over all points (m k d distance terms per iteration).
//
// Errors: ValidatePoints' INVALID_ARGUMENT; INVALID_ARGUMENT naming 'min_clusters' (not in
// [1, m]), 'max_clusters' (below min_clusters or above m), 'split_trials' (0),
// 'max_iterations' (0), 'tolerance' (negative or NaN) or 'threads' (< 0); RunKmeans'
// errors; CANCELLED where options.cancel was set.
absl::StatusOr<XmeansResult> RunXmeans(const PointSet& points, const XmeansOptions& options);

}  // namespace mlclust

#endif  // MLCLUST_CORE_CLUSTER_XMEANS_H_
