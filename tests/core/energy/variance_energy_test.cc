#include "core/energy/variance_energy.h"

#include <gtest/gtest.h>

#include <vector>

#include "core/base/ids.h"
#include "core/base/random.h"
#include "core/energy/energies.h"

namespace mlclust {
namespace {

// Eq. 6.5 by its definition: means first, then squared distances.
double DirectEnergy(const PointSet& points, const std::vector<uint32_t>& labels, uint32_t k) {
  const uint32_t d = points.dims;
  std::vector<double> mean(size_t{k} * d, 0.0), count(k, 0.0);
  for (size_t i = 0; i < labels.size(); ++i) {
    ++count[labels[i]];
    for (uint32_t j = 0; j < d; ++j) mean[labels[i] * d + j] += points.values[i * d + j];
  }
  for (uint32_t c = 0; c < k; ++c) {
    for (uint32_t j = 0; j < d; ++j) mean[c * d + j] /= count[c];
  }
  double energy = 0;
  for (size_t i = 0; i < labels.size(); ++i) {
    for (uint32_t j = 0; j < d; ++j) {
      const double diff = points.values[i * d + j] - mean[labels[i] * d + j];
      energy += diff * diff;
    }
  }
  return energy;
}

PointSet RandomPoints(size_t m, uint32_t d, uint64_t seed) {
  Random random(seed);
  PointSet points{d, {}};
  for (size_t i = 0; i < m * d; ++i) points.values.push_back(static_cast<float>(random.Unit()));
  return points;
}

TEST(VarianceEnergyTest, TwoPointsHaveHalfTheirSquaredDistance) {
  const PointSet points{2, {0, 0, 3, 4}};
  const VarianceEnergy energy(points);
  const VarianceEnergy::Sums both = energy.element_sums(0) + energy.element_sums(1);
  EXPECT_DOUBLE_EQ(energy.Energy(both), 12.5);
  EXPECT_DOUBLE_EQ(energy.MergeCost(energy.element_sums(0), energy.element_sums(1)), 12.5);
  EXPECT_EQ(energy.Energy(energy.element_sums(0)), 0.0);
  EXPECT_EQ(energy.Energy(VarianceEnergy::Sums()), 0.0);
}

// The incremental form, the proxies' sum and the definition agree; the merge cost is the
// energy difference; removing an element's sums undoes adding them.
TEST(VarianceEnergyTest, IncrementalFormProxiesAndMergeCostMatchTheDefinition) {
  for (uint32_t d : {1u, 3u, 7u}) {
    const PointSet points = RandomPoints(300, d, 40 + d);
    const VarianceEnergy energy(points);
    const uint32_t k = 5;
    std::vector<uint32_t> labels(300);
    std::vector<ClusterId> ids(300);
    for (size_t i = 0; i < labels.size(); ++i) {
      labels[i] = static_cast<uint32_t>((i * 7 + i / 13) % k);
      ids[i] = ClusterId(labels[i]);
    }
    const double direct = DirectEnergy(points, labels, k);
    EXPECT_NEAR(EnergyFromSums(energy, ids), direct, 1e-9 * direct) << d;
    EXPECT_NEAR(EnergyFromProxies(energy, ids), direct, 1e-9 * direct) << d;

    std::vector<VarianceEnergy::Sums> sums(k);
    for (uint32_t i = 0; i < labels.size(); ++i) sums[labels[i]] += energy.element_sums(i);
    const double merged = energy.Energy(sums[1] + sums[3]);
    EXPECT_NEAR(energy.MergeCost(sums[1], sums[3]),
                merged - energy.Energy(sums[1]) - energy.Energy(sums[3]), 1e-9 * merged);
    VarianceEnergy::Sums back = sums[2];
    back += energy.element_sums(7);
    back -= energy.element_sums(7);
    EXPECT_NEAR(energy.Energy(back), energy.Energy(sums[2]), 1e-12 * energy.Energy(sums[2]));
  }
}

// Points far from the origin of their coordinates: sums relative to the data's mean keep
// the energy of a tight cluster exact where raw sums would cancel.
TEST(VarianceEnergyTest, FarFromTheCoordinateOriginTheEnergyKeepsItsPrecision) {
  const PointSet points{1, {1e6f, 1e6f + 1, 1e6f + 2}};
  const VarianceEnergy energy(points);
  const VarianceEnergy::Sums all =
      energy.element_sums(0) + energy.element_sums(1) + energy.element_sums(2);
  EXPECT_DOUBLE_EQ(energy.Energy(all), 2.0);
  EXPECT_DOUBLE_EQ(energy.ElementCost(0, energy.FitProxy(all)), 1.0);
}

}  // namespace
}  // namespace mlclust
