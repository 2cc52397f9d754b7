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
//
// Why line 2's stop needs a look-ahead (ours, XmeansOptions::lookahead): on blobs spread
// over a volume the BIC has a local maximum at K = 1 (and often at 2 or 3). One 2-means cut
// of such a cloud removes only 25-40% of its energy (a uniform cube: 25%), while halving
// the mixing weights costs R ln 2 in the log-likelihood, so for R points in M dimensions the
// split passes only where the energy falls below 2^(-2/M) of the cluster's (63% in 3-D):
// from k_min = 1 the first round keeps no split and Alg. 2.5 stops at one cluster
// (50 Gaussians of Fig. 6.15: BIC -309,102 at K = 1, -310,828 at K = 2, and ML's levels
// rise above both from K = 8 on; bench/pages/fidelity.md). This is the text's own remark
// on Fig. 6.16 (l. 2812: local maxima of the BIC between 1 and 100 clusters trap X-means).
// With a look-ahead of L, a round that keeps no split splits every cluster anyway (a forced
// round, k doubling within k_max), as long as fewer than L forced rounds have run since the
// last round that raised the largest BIC; the search ends when L forced rounds in a row
// bring no model of larger BIC, and the result is still the round of the largest BIC.
// L = 0 is Alg. 2.5 as the text writes it.
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
  // Ours (see above): forced rounds allowed since the last round that raised the largest
  // BIC; 0: Alg. 2.5's stop at the first round that keeps no split. Each forced round
  // costs a round at up to twice the clusters, so the search ends after rounds at up to
  // 2^L times the clusters of the result.
  uint32_t lookahead = 2;
};

struct XmeansRound {
  uint32_t clusters = 0;  // k after the round's k-means
  double inertia = 0;     // its energy (sum of squared distances to the cluster means)
  double bic = 0;         // its BIC over all points
  uint32_t splits = 0;    // splits the round applied (0 for the first k-means)
  bool forced = false;    // a forced round (XmeansOptions::lookahead): no split passed
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
  // Why the search ended: no virtual split raised the local BIC (after `lookahead` forced
  // rounds without a larger BIC), or k reached k_max.
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
