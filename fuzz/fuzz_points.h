// What fuzz_csv and fuzz_npy share: the promises of a points decoder checked on its result.
#ifndef MLCLUST_FUZZ_FUZZ_POINTS_H_
#define MLCLUST_FUZZ_FUZZ_POINTS_H_

#include <cstddef>
#include <cstdint>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/io/points_io.h"
#include "core/points/points.h"
#include "fuzz/fuzz_check.h"

namespace mlclust::fuzz {

// The fuzzer's bytes as the text a decoder takes.
inline absl::string_view AsBytes(const uint8_t* data, size_t size) {
  return absl::string_view(reinterpret_cast<const char*>(data), size);
}

// An error must be INVALID_ARGUMENT and a point set must pass ValidatePoints with `limits`
// (as points_io.h promises); returns whether there is a point set to check further.
inline bool CheckDecodedPoints(const absl::StatusOr<PointSet>& points, const PointLimits& limits) {
  if (!points.ok()) {
    MLCLUST_FUZZ_CHECK(points.status().code() == absl::StatusCode::kInvalidArgument);
    return false;
  }
  MLCLUST_FUZZ_CHECK(ValidatePoints(*points, limits).ok());
  return true;
}

}  // namespace mlclust::fuzz

#endif  // MLCLUST_FUZZ_FUZZ_POINTS_H_
