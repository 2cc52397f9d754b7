// Point sets built in code for tests.
#ifndef MLCLUST_TESTS_CORE_TEST_POINTS_H_
#define MLCLUST_TESTS_CORE_TEST_POINTS_H_

#include <cmath>
#include <numbers>
#include <utility>
#include <vector>

#include "core/points.h"
#include "core/random.h"

namespace mlclust::testing {

struct Blobs {
  PointSet points;
  std::vector<uint32_t> truth;  // generating cluster per point, 0..K-1
};

// `clusters` spherical Gaussians (sigma 1) of `per_cluster` points each in 3-D, centres
// uniform in [-25, 25]^3 and at least `separation` apart (rejection sampling). Points are
// listed cluster after cluster, or, with `shuffle`, in a random order so that blocks of
// rows mix clusters.
inline Blobs GaussianBlobs(uint32_t clusters, uint32_t per_cluster, double separation,
                           uint64_t seed, bool shuffle = false) {
  Random random(seed);
  std::vector<double> centres;
  while (centres.size() < 3 * clusters) {
    double c[3];
    for (double& v : c) v = -25 + 50 * random.Unit();
    bool far = true;
    for (size_t o = 0; o < centres.size(); o += 3) {
      double d2 = 0;
      for (int j = 0; j < 3; ++j) d2 += (c[j] - centres[o + j]) * (c[j] - centres[o + j]);
      far = far && d2 >= separation * separation;
    }
    if (far) centres.insert(centres.end(), c, c + 3);
  }
  const size_t m = size_t{clusters} * per_cluster;
  std::vector<uint32_t> row(m);
  for (size_t i = 0; i < m; ++i) row[i] = static_cast<uint32_t>(i);
  if (shuffle) {
    for (size_t i = m; i > 1; --i) std::swap(row[i - 1], row[random.Below(i)]);
  }
  Blobs blobs;
  blobs.points.dims = 3;
  blobs.points.values.resize(3 * m);
  blobs.truth.resize(m);
  for (size_t n = 0; n < m; ++n) {
    const uint32_t c = static_cast<uint32_t>(n / per_cluster);
    blobs.truth[row[n]] = c;
    for (int j = 0; j < 3; ++j) {
      const double u1 = 1 - random.Unit();
      const double u2 = random.Unit();
      const double normal = std::sqrt(-2 * std::log(u1)) * std::cos(2 * std::numbers::pi * u2);
      blobs.points.values[3 * size_t{row[n]} + j] = static_cast<float>(centres[3 * c + j] + normal);
    }
  }
  return blobs;
}

}  // namespace mlclust::testing

#endif  // MLCLUST_TESTS_CORE_TEST_POINTS_H_
