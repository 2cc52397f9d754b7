// A points job's input as the server receives it: m x d float32, little-endian, row-major,
// with d from the spec. The server (server/job_runner.cc, RunPointsJob) has no library
// function for the conversion; this target repeats its steps (d = 0 and a partial point
// refused, the bytes copied into a PointSet, ValidatePoints) and then runs the voxel-grid
// start every ML/PML/HC points job begins with, on the hostile coordinates.
//
// Input: the first byte is d (0 tests the refusal), the second the grid (0 = chosen from
// m and d, as the server's default), the rest the float32 values.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>

#include "core/cluster/point_clustering.h"
#include "core/points/points.h"
#include "fuzz/fuzz_check.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace mlclust;
  if (size < 2) return 0;
  const uint32_t d = data[0];
  const uint32_t grid = data[1];
  data += 2;
  size -= 2;
  if (d == 0 || size % (size_t{4} * d) != 0) return 0;  // refused by the server
  PointSet points;
  points.dims = d;
  points.values.resize(size / 4);
  if (size != 0) std::memcpy(points.values.data(), data, size);
  if (!ValidatePoints(points).ok()) return 0;
  MLCLUST_FUZZ_CHECK(points.num_points() > 0);
  absl::StatusOr<VoxelStart> start = VoxelGridStart(points, grid);
  MLCLUST_FUZZ_CHECK(start.ok());
  MLCLUST_FUZZ_CHECK(start->labels.size() == points.num_points());
  MLCLUST_FUZZ_CHECK(start->clusters >= 1 && start->clusters <= points.num_points());
  for (ClusterId label : start->labels) MLCLUST_FUZZ_CHECK(label.value() < start->clusters);
  return 0;
}
