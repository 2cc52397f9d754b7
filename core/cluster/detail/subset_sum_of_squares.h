// What X-means and bisecting k-means share: the within-cluster sum of squares of a subset
// of points from its definition, the subset as a point set, and the check of the options
// they pass to the k-means they run on a subset.
#ifndef MLCLUST_CORE_CLUSTER_DETAIL_SUBSET_SUM_OF_SQUARES_H_
#define MLCLUST_CORE_CLUSTER_DETAIL_SUBSET_SUM_OF_SQUARES_H_

#include <algorithm>
#include <cstdint>
#include <span>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "core/cluster/kmeans.h"
#include "core/points/points.h"

namespace mlclust::detail {

// Sum of squared distances of `members` to their mean, in double and in two passes (the
// mean, then the distances), which keeps far-from-origin data exact to rounding. Used by
// X-means and bisecting k-means for the energies they compare and report. With `mean_out`,
// the mean is left there.
inline double SubsetSumOfSquares(const PointSet& points, const std::vector<uint32_t>& members,
                                 std::vector<double>* mean_out = nullptr) {
  const uint32_t d = points.dims;
  std::vector<double> local;
  std::vector<double>& mean = mean_out != nullptr ? *mean_out : local;
  mean.assign(d, 0.0);
  for (uint32_t i : members) {
    const std::span<const float> p = points.point(PointId(i));
    for (uint32_t j = 0; j < d; ++j) mean[j] += p[j];
  }
  for (double& v : mean) v /= static_cast<double>(members.size());
  double sse = 0;
  for (uint32_t i : members) {
    const std::span<const float> p = points.point(PointId(i));
    for (uint32_t j = 0; j < d; ++j) {
      const double diff = p[j] - mean[j];
      sse += diff * diff;
    }
  }
  return sse;
}

// The points `members` (ids into `points`) as a set of their own, in that order. Used by
// X-means and bisecting k-means to run k-means on one cluster.
inline PointSet Subset(const PointSet& points, const std::vector<uint32_t>& members) {
  PointSet subset;
  subset.dims = points.dims;
  subset.values.resize(members.size() * points.dims);
  float* out = subset.values.data();
  for (uint32_t i : members) {
    const std::span<const float> p = points.point(PointId(i));
    out = std::copy(p.begin(), p.end(), out);
  }
  return subset;
}

// OK, or INVALID_ARGUMENT naming the option: max_iterations < 1, tolerance not >= 0 (NaN
// too), threads < 0.
inline absl::Status CheckInnerKmeansOptions(const KmeansRunOptions& options) {
  const double tolerance = options.tolerance;
  const int threads = options.threads;
  if (options.max_iterations < 1) {
    return absl::InvalidArgumentError("'max_iterations' must be at least 1");
  }
  if (!(tolerance >= 0)) {
    return absl::InvalidArgumentError(absl::StrCat("'tolerance' must be >= 0, not ", tolerance));
  }
  if (threads < 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("'threads' must be >= 0 (0: all cores), not ", threads));
  }
  return absl::OkStatus();
}

}  // namespace mlclust::detail

#endif  // MLCLUST_CORE_CLUSTER_DETAIL_SUBSET_SUM_OF_SQUARES_H_
