#include "core/points/points.h"

#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"

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

absl::StatusOr<std::vector<uint32_t>> VoxelStartCells(
    size_t m, std::span<const float> lo, std::span<const float> hi, uint32_t grid,
    const std::atomic<bool>* cancel,
    const std::function<absl::StatusOr<uint32_t>(std::span<const uint32_t>)>& occupied) {
  const uint32_t d = static_cast<uint32_t>(lo.size());
  if (grid != 0) return std::vector<uint32_t>(d, grid);
  const double target = std::max(1.0, static_cast<double>(m) / 8.0);
  const double a = std::pow(target, 1.0 / d);
  if (a >= 4) {
    return std::vector<uint32_t>(d, static_cast<uint32_t>(std::min(a, 4096.0)));
  }
  std::vector<uint32_t> counts(d, 1);
  for (int pass = 0; pass < 64; ++pass) {
    absl::StatusOr<uint32_t> found = occupied(counts);
    if (!found.ok()) return found.status();
    const double cells = static_cast<double>(*found);
    if (IsCancelled(cancel) || cells >= target) break;
    // Halve the widest cells on enough axes to multiply the cells by target / cells.
    const int axes = std::max(1, static_cast<int>(std::ceil(std::log2(target / cells))));
    bool any = false;
    for (int step = 0; step < axes; ++step) {
      uint32_t widest = d;
      double width = 0;
      for (uint32_t j = 0; j < d; ++j) {
        const double w = (static_cast<double>(hi[j]) - lo[j]) / counts[j];
        if (w > width && counts[j] < 4096) {
          width = w;
          widest = j;
        }
      }
      if (widest == d) break;
      counts[widest] *= 2;
      any = true;
    }
    if (!any) break;
  }
  return counts;
}

}  // namespace mlclust
