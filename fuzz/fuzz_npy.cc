// DecodePointsNpy: the .npy reader (format 1.0/2.0/3.0 headers, float32/float64 in either
// byte order, C and Fortran order) on bytes in memory. Every result must pass
// ValidatePoints, as points_io.h promises.
#include <cstddef>
#include <cstdint>

#include "core/io/points_io.h"
#include "fuzz/fuzz_check.h"
#include "fuzz/fuzz_points.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace mlclust;
  PointReadOptions options;
  options.limits.max_values = uint64_t{1} << 24;  // keeps a declared shape from costing time
  const absl::StatusOr<PointSet> points = DecodePointsNpy(fuzz::AsBytes(data, size), options);
  if (!fuzz::CheckDecodedPoints(points, options.limits)) return 0;
  MLCLUST_FUZZ_CHECK(points->values.size() * 4 <= size);
  return 0;
}
