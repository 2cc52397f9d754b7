// Point sets: m points in d dimensions, float32, row-major (point i is values[i*d .. i*d+d)).
// A point's index is its id (PointId, core/base/ids.h) on the wire and in every output.
#ifndef MLCLUST_CORE_POINTS_POINTS_H_
#define MLCLUST_CORE_POINTS_POINTS_H_

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "core/base/ids.h"

namespace mlclust {

struct PointSet {
  uint32_t dims = 0;
  std::vector<float> values;  // num_points() * dims floats

  size_t num_points() const { return dims == 0 ? 0 : values.size() / dims; }
  // Point `id`'s `dims` coordinates (ids are 0 .. num_points() - 1).
  std::span<const float> point(PointId id) const { return point(size_t{id.value()}); }
  // The same by raw index, for loops over 0 .. num_points() - 1.
  std::span<const float> point(size_t i) const { return {values.data() + i * dims, dims}; }
};

// Limits for untrusted point sets.
struct PointLimits {
  uint32_t max_dims = 1024;
  uint64_t max_values = uint64_t{1} << 31;  // m * d
};

// OK, or INVALID_ARGUMENT naming the problem: d = 0 or over the limit, m = 0, values not a
// whole number of points, m * d over the limit, a NaN or infinite value (which point and
// which coordinate).
absl::Status ValidatePoints(const PointSet& points, const PointLimits& limits = {});

// The cells per axis of the voxel start for `m` points in the box [lo, hi]: `grid` on every
// axis when it is not 0; otherwise aiming at eight points per cell, (m / 8)^(1/d) on every
// axis where that is at least 4, else the widest cells halved a few axes at a time until
// about m / 8 cells are occupied, `occupied` counting the occupied cells of each trial
// (the CPU counts them in one sweep, the GPU's voxel start on the device; its error is
// returned). Once `cancel` is set it stops early (the caller checks it).
absl::StatusOr<std::vector<uint32_t>> VoxelStartCells(
    size_t m, std::span<const float> lo, std::span<const float> hi, uint32_t grid,
    const std::atomic<bool>* cancel,
    const std::function<absl::StatusOr<uint32_t>(std::span<const uint32_t>)>& occupied);

}  // namespace mlclust

#endif  // MLCLUST_CORE_POINTS_POINTS_H_
