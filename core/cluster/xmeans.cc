#include "core/cluster/xmeans.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"
#include "core/base/random.h"
#include "core/base/status_macros.h"
#include "core/cluster/detail/subset_sum_of_squares.h"
#include "core/hierarchy/model_selection.h"

namespace mlclust {
namespace {

// Below this many points a 2-means run stays on the calling thread.
constexpr size_t kParallelPoints = 65536;

absl::Status CheckOptions(const PointSet& points, const XmeansOptions& options) {
  MLCLUST_RETURN_IF_ERROR(ValidatePoints(points));
  const size_t m = points.num_points();
  if (options.min_clusters < 1 || options.min_clusters > m) {
    return absl::InvalidArgumentError(absl::StrCat("'min_clusters' must be in [1, ", m,
                                                   "] (the number of points), not ",
                                                   options.min_clusters));
  }
  if (options.max_clusters != 0 &&
      (options.max_clusters < options.min_clusters || options.max_clusters > m)) {
    return absl::InvalidArgumentError(
        absl::StrCat("'max_clusters' must be 0 (the number of points) or in [min_clusters = ",
                     options.min_clusters, ", ", m, "], not ", options.max_clusters));
  }
  if (options.split_trials < 1) {
    return absl::InvalidArgumentError("'split_trials' must be at least 1");
  }
  return detail::CheckInnerKmeansOptions(options);
}

// The points of each cluster (labels 0..k-1), by a counting sort.
std::vector<std::vector<uint32_t>> MembersOf(const std::vector<ClusterId>& labels, uint32_t k) {
  std::vector<std::vector<uint32_t>> members(k);
  for (size_t i = 0; i < labels.size(); ++i) {
    members[labels[i].value()].push_back(static_cast<uint32_t>(i));
  }
  return members;
}

// The BIC of a whole labelling (sizes from the labels).
double ModelBic(const std::vector<ClusterId>& labels, uint32_t k, double inertia, uint32_t dims) {
  std::vector<uint64_t> sizes(k, 0);
  for (ClusterId label : labels) ++sizes[label.value()];
  return SphericalGaussianBic(sizes, inertia, labels.size(), dims);
}

struct Split {
  uint32_t cluster = 0;
  double gain = 0;             // BIC(two halves) - BIC(one), on the cluster's points
  std::vector<float> centres;  // 2 x d, the halves' means
};

}  // namespace

absl::StatusOr<XmeansResult> RunXmeans(const PointSet& points, const XmeansOptions& options) {
  MLCLUST_RETURN_IF_ERROR(CheckOptions(points, options));
  const size_t m = points.num_points();
  const uint32_t d = points.dims;
  const uint32_t k_max =
      options.max_clusters == 0 ? static_cast<uint32_t>(m) : options.max_clusters;
  Random seeds(options.seed);

  // Alg. 2.5 lines 1-2: k-means with k_min clusters.
  KmeansOptions kmeans = KmeansOptionsFor(options, options.min_clusters);
  kmeans.seed = seeds.Next();
  MLCLUST_ASSIGN_OR_RETURN(KmeansResult current, RunKmeans(points, kmeans));
  uint32_t k = options.min_clusters;

  XmeansResult result;
  // Forced rounds since the last round that raised the largest BIC (XmeansOptions::lookahead).
  uint32_t forced_since_best = 0;
  auto record = [&](uint32_t splits, bool forced) {
    const double bic = ModelBic(current.labels, k, current.inertia, d);
    result.rounds.push_back({k, current.inertia, bic, splits, forced});
    if (result.rounds.size() == 1 || bic > result.bic) {
      forced_since_best = 0;
      result.chosen_round = result.rounds.size() - 1;
      result.labels = current.labels;
      result.centres = current.centres;
      result.inertia = current.inertia;
      result.bic = bic;
      result.clusters = k;
    }
  };
  record(0, false);

  KmeansOptions two_means = kmeans;
  two_means.clusters = 2;
  while (true) {
    if (k >= k_max) {
      result.stopped_at_max = true;
      break;
    }
    // Lines 4-5: each cluster split virtually by 2-means on its own points; the split is
    // kept where it raises the BIC of those points (PM00's local model comparison).
    const std::vector<std::vector<uint32_t>> members = MembersOf(current.labels, k);
    std::vector<Split> splits;
    std::vector<Split> rejected;  // the splits a forced round applies
    for (uint32_t c = 0; c < k; ++c) {
      MLCLUST_RETURN_IF_ERROR(CheckCancelled(
          options.cancel, absl::StrCat("X-means round ", result.rounds.size(), " cluster ", c)));
      const std::vector<uint32_t>& cluster = members[c];
      const uint64_t n = cluster.size();
      if (n < 3) continue;
      const PointSet subset = detail::Subset(points, cluster);
      two_means.threads = n >= kParallelPoints ? options.threads : 1;
      KmeansResult best;
      for (uint32_t trial = 0; trial < options.split_trials; ++trial) {
        two_means.seed = seeds.Next();
        MLCLUST_ASSIGN_OR_RETURN(KmeansResult run, RunKmeans(subset, two_means));
        if (trial == 0 || run.inertia < best.inertia) best = std::move(run);
      }
      uint64_t sizes[2] = {0, 0};
      for (ClusterId label : best.labels) ++sizes[label.value()];
      const double one = SphericalGaussianBic(std::span<const uint64_t>(&n, 1),
                                              detail::SubsetSumOfSquares(points, cluster), n, d);
      const double two = SphericalGaussianBic(sizes, best.inertia, n, d);
      if (two > one) {
        splits.push_back({c, two - one, std::move(best.centres)});
      } else if (splits.empty() && forced_since_best < options.lookahead) {
        rejected.push_back({c, two - one, std::move(best.centres)});
      }
    }
    // No split passed: Alg. 2.5 ends here, unless the look-ahead (ours) allows a forced round
    // that splits every cluster the test rejected.
    const bool forced = splits.empty() && !rejected.empty();
    if (forced) {
      splits = std::move(rejected);
      ++forced_since_best;
    }
    if (splits.empty()) break;
    // Best gain first (ties to the smaller cluster id), as many as k_max allows.
    std::stable_sort(splits.begin(), splits.end(),
                     [](const Split& a, const Split& b) { return a.gain > b.gain; });
    if (splits.size() > k_max - k) splits.resize(k_max - k);
    std::sort(splits.begin(), splits.end(),
              [](const Split& a, const Split& b) { return a.cluster < b.cluster; });

    // The first half takes the cluster's place, the second is appended.
    std::vector<float> centres = current.centres;
    for (const Split& split : splits) {
      std::copy_n(split.centres.begin(), d, centres.begin() + size_t{split.cluster} * d);
      centres.insert(centres.end(), split.centres.begin() + d, split.centres.end());
    }
    k += static_cast<uint32_t>(splits.size());
    MLCLUST_RETURN_IF_ERROR(
        CheckCancelled(options.cancel, absl::StrCat("X-means round ", result.rounds.size())));
    // Line 5 (PM00's Improve-Params): k-means over all points from those centres.
    kmeans.clusters = k;
    MLCLUST_ASSIGN_OR_RETURN(current, RunLloyd(points, std::move(centres), kmeans));
    record(static_cast<uint32_t>(splits.size()), forced);
  }
  return result;
}

}  // namespace mlclust
