// Gaussian blobs, the point benches' data (points_bench, points_gpu_bench).
#ifndef MLCLUST_BENCH_BLOBS_H_
#define MLCLUST_BENCH_BLOBS_H_

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/base/random.h"
#include "core/cluster/point_clustering.h"

namespace mlclust::bench {

// Blobs: centres uniform in [-25, 25]^d, sigma 1, each point from a random centre.
inline PointSet Blobs(uint64_t m, uint32_t d, uint32_t blobs, uint64_t seed) {
  Random random(seed);
  PointSet points;
  points.dims = d;
  std::vector<double> centres(size_t{blobs} * d);
  for (double& c : centres) c = -25 + 50 * random.Unit();
  points.values.resize(m * d);
  for (uint64_t i = 0; i < m; ++i) {
    const uint64_t b = random.Below(blobs);
    for (uint32_t j = 0; j < d; ++j) {
      const double u = std::max(random.Unit(), 1e-300), v = random.Unit();
      points.values[i * d + j] = static_cast<float>(
          centres[b * d + j] + std::sqrt(-2 * std::log(u)) * std::cos(6.283185307179586 * v));
    }
  }
  return points;
}

}  // namespace mlclust::bench

#endif  // MLCLUST_BENCH_BLOBS_H_
