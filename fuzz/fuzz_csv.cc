// DecodePointsText: the CSV / whitespace-separated text reader (header line, BOM, CRLF,
// padded fields, from_chars numbers) on bytes in memory. Every result must pass
// ValidatePoints, as points_io.h promises. The first byte, when it is below 8, is the
// dims option (0: from the file), so that the dims check is fuzzed too.
#include <cstddef>
#include <cstdint>

#include "core/io/points_io.h"
#include "fuzz/fuzz_check.h"
#include "fuzz/fuzz_points.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace mlclust;
  PointReadOptions options;
  if (size > 0 && data[0] < 8) {
    options.dims = data[0];
    ++data;
    --size;
  }
  const absl::StatusOr<PointSet> points = DecodePointsText(fuzz::AsBytes(data, size), options);
  if (!fuzz::CheckDecodedPoints(points, options.limits)) return 0;
  MLCLUST_FUZZ_CHECK(options.dims == 0 || points->dims == options.dims);
  return 0;
}
