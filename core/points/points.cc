#include "core/points/points.h"

#include <cmath>

#include "absl/strings/str_cat.h"

namespace mlclust {

absl::Status ValidatePoints(const PointSet& points, const PointLimits& limits) {
  if (points.dims == 0) return absl::InvalidArgumentError("points: d = 0 dimensions");
  if (points.dims > limits.max_dims) {
    return absl::InvalidArgumentError(absl::StrCat(
        "points: d = ", points.dims, " dimensions is over the limit of ", limits.max_dims));
  }
  if (points.values.size() % points.dims != 0) {
    return absl::InvalidArgumentError(absl::StrCat("points: ", points.values.size(),
                                                   " values are not a whole number of ",
                                                   points.dims, "-dimensional points"));
  }
  if (points.values.empty()) return absl::InvalidArgumentError("points: m = 0 points");
  if (points.values.size() > limits.max_values) {
    return absl::InvalidArgumentError(absl::StrCat("points: m x d = ", points.values.size(),
                                                   " values is over the limit of ",
                                                   limits.max_values));
  }
  for (size_t i = 0; i < points.values.size(); ++i) {
    if (!std::isfinite(points.values[i])) {
      return absl::InvalidArgumentError(absl::StrCat("points: point ", i / points.dims,
                                                     " coordinate ", i % points.dims, " is ",
                                                     points.values[i]));
    }
  }
  return absl::OkStatus();
}

}  // namespace mlclust
