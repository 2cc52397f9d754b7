// The argument checks that every point multilevel run makes, the CPU's
// (RunPointMultilevel) and the GPU's (gpu/stages/points_multilevel_gpu.h). Internal to
// core/cluster.
#ifndef MLCLUST_CORE_CLUSTER_DETAIL_POINT_LEVELS_CHECKS_H_
#define MLCLUST_CORE_CLUSTER_DETAIL_POINT_LEVELS_CHECKS_H_

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "core/base/status_macros.h"
#include "core/cluster/point_clustering.h"
#include "core/points/points.h"

namespace mlclust::detail {

// INVALID_ARGUMENT for invalid points (ValidatePoints), a lowest level under 1 cluster,
// negative threads or a grid over 2^20 cells per axis.
inline absl::Status CheckPointLevelsArguments(const PointSet& points,
                                              const PointMultilevelOptions& options) {
  MLCLUST_RETURN_IF_ERROR(ValidatePoints(points));
  if (options.min_clusters < 1) {
    return absl::InvalidArgumentError("clusters: the lowest level must have at least 1");
  }
  if (options.threads < 0) {
    return absl::InvalidArgumentError(absl::StrCat("threads: ", options.threads, " < 0"));
  }
  if (options.grid > (1u << 20)) {
    return absl::InvalidArgumentError(absl::StrCat("grid: ", options.grid, " is over 2^20"));
  }
  return absl::OkStatus();
}

// The checks of an LN k-means run from given labels, the CPU's (RunLnKmeans) and the GPU's
// (gpu/stages/point_stages_gpu.h): INVALID_ARGUMENT for invalid points (ValidatePoints) or
// not one label per point.
inline absl::Status CheckLnKmeansArguments(const PointSet& points, size_t labels) {
  MLCLUST_RETURN_IF_ERROR(ValidatePoints(points));
  if (labels != points.num_points()) {
    return absl::InvalidArgumentError(
        absl::StrCat("labels: ", labels, " for ", points.num_points(), " points"));
  }
  return absl::OkStatus();
}

}  // namespace mlclust::detail

#endif  // MLCLUST_CORE_CLUSTER_DETAIL_POINT_LEVELS_CHECKS_H_
