#include "gpu/kernels/cluster_sums.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "core/base/compensated_sum.h"
#include "core/energy/energies.h"
#include "core/mesh/face_measures.h"
#include "gpu/context/gl_context.h"
#include "gpu/tools/test_meshes.h"
#include "tests/fixtures/gl_test_context.h"

namespace mlclust::gpu {
namespace {

std::unique_ptr<GlContext> MakeContext() { return ::mlclust::testing::MakeGlContext(); }

TEST(ClusterSums, SmallIntegersAreExact) {
  std::unique_ptr<GlContext> context = MakeContext();
  ASSERT_NE(context, nullptr);
  // 100 elements of 3 values; cluster 3 empty; cluster 0 spans several chunks.
  const uint32_t n = 100, d = 3, k = 5;
  std::vector<uint32_t> labels(n);
  std::vector<double> values(n * d);
  for (uint32_t i = 0; i < n; ++i) {
    labels[i] = i < 70 ? 0 : (i % 3 == 0 ? 1 : (i % 3 == 1 ? 2 : 4));
    for (uint32_t j = 0; j < d; ++j) values[i * d + j] = static_cast<double>(i * 10 + j);
  }
  absl::StatusOr<std::vector<double>> sums = SumByCluster(*context, values, d, labels, k);
  ASSERT_TRUE(sums.ok()) << sums.status();
  EXPECT_EQ(*sums, SumByClusterCpu(values, d, labels, k));
  // Cluster 0: sum over i < 70 of 10 i + j.
  EXPECT_EQ((*sums)[0], 10.0 * 69 * 70 / 2);
  EXPECT_EQ((*sums)[2], 10.0 * 69 * 70 / 2 + 2 * 70);
  EXPECT_EQ((*sums)[3 * d], 0.0);
}

// With at most 8 work groups per grid dimension, both passes run as 2-D grids (6,250
// chunk invocations = 25 groups: 8 x 4): integer sums stay exact.
TEST(ClusterSums, TwoDimensionalGridsGiveTheSameSums) {
  GlContextOptions options;
  options.max_groups_per_dimension = 8;
  absl::StatusOr<std::unique_ptr<GlContext>> context = GlContext::Create(options);
  ASSERT_TRUE(context.ok()) << context.status();
  const uint32_t n = 200000, d = 2, k = 3000;
  std::mt19937 random(9);
  std::uniform_int_distribution<uint32_t> pick(0, k - 1);
  std::vector<uint32_t> labels(n);
  std::vector<double> values(size_t{n} * d);
  for (uint32_t i = 0; i < n; ++i) {
    labels[i] = i < n / 2 ? 7 : pick(random);
    values[size_t{i} * d] = i % 1000;
    values[size_t{i} * d + 1] = 1;
  }
  absl::StatusOr<std::vector<double>> sums = SumByCluster(**context, values, d, labels, k);
  ASSERT_TRUE(sums.ok()) << sums.status();
  EXPECT_EQ(*sums, SumByClusterCpu(values, d, labels, k));
}

TEST(ClusterSums, RejectsBadInputs) {
  std::unique_ptr<GlContext> context = MakeContext();
  ASSERT_NE(context, nullptr);
  const std::vector<double> values = {1, 2, 3, 4};
  const std::vector<uint32_t> labels = {0, 1};
  EXPECT_EQ(SumByCluster(*context, values, 2, labels, 1).status().code(),
            absl::StatusCode::kInvalidArgument);  // label 1 >= 1 cluster
  EXPECT_EQ(SumByCluster(*context, values, 3, labels, 2).status().code(),
            absl::StatusCode::kInvalidArgument);  // 4 values for 2 x 3
  EXPECT_EQ(SumByCluster(*context, values, 0, labels, 2).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE(SumByCluster(*context, values, 2, labels, 2).ok());
}

// A 500 x 1000 grid (10^6 faces) whose row heights grow geometrically from 1e-6 to 1e6:
// face areas over twelve orders of magnitude, and large centroids, so the squared-norm
// sums reach 1e20 beside terms of 1e-12.
TriangleMesh GradedGrid() {
  const uint32_t rows = 500, cols = 1000;
  TriangleMesh mesh = testing::MakeJitteredGrid(rows, cols, 0.2f, 7);
  const double ratio = std::pow(1e12, 1.0 / rows);
  for (size_t v = 0; v < mesh.positions.size() / 3; ++v) {
    const double y = mesh.positions[3 * v + 1];
    mesh.positions[3 * v + 1] = static_cast<float>(1e-6 * (std::pow(ratio, y) - 1) / (ratio - 1));
  }
  return mesh;
}

TEST(ClusterSums, MatchesFp64OnAMillionFacesOfVeryDifferentAreas) {
  std::unique_ptr<GlContext> context = MakeContext();
  ASSERT_NE(context, nullptr);
  const TriangleMesh mesh = GradedGrid();
  const FaceMeasures measures = ComputeFaceMeasures(mesh);
  const size_t n = measures.num_faces();
  ASSERT_EQ(n, 1000000u);
  const auto [min_area, max_area] = std::minmax_element(measures.area.begin(), measures.area.end());
  ASSERT_GT(*max_area / *min_area, 1e10);
  const CvdEnergy energy(measures);

  // k = 1001: one cluster of every other face (spans every chunk), the rest at random over
  // 1000 clusters, a few of which stay empty.
  const uint32_t k = 1001;
  std::mt19937 random(3);
  std::uniform_int_distribution<uint32_t> pick(1, k - 1);
  std::vector<uint32_t> labels(n);
  for (size_t f = 0; f < n; ++f) labels[f] = f % 2 == 0 ? 0 : pick(random);
  for (size_t f = 0; f < n; ++f) {
    if (labels[f] >= 990) labels[f] = 1;  // clusters 990..1000 empty
  }

  absl::StatusOr<std::vector<CvdSums>> sums = EnergyClusterSums(*context, energy, labels, k);
  ASSERT_TRUE(sums.ok()) << sums.status();
  ASSERT_EQ(sums->size(), k);

  // The reference: compensated fp64 sums, and the sums of absolute values for the bound.
  constexpr int kValues = 5;
  std::vector<mlclust::detail::CompensatedSum> reference(size_t{k} * kValues);
  std::vector<double> magnitude(size_t{k} * kValues, 0.0);
  for (size_t f = 0; f < n; ++f) {
    const CvdSums& s = energy.face_sums(static_cast<uint32_t>(f));
    const double terms[kValues] = {s.area, s.weighted_centroid.x, s.weighted_centroid.y,
                                   s.weighted_centroid.z, s.weighted_squared_norm};
    for (int j = 0; j < kValues; ++j) {
      reference[labels[f] * kValues + j].Add(terms[j]);
      magnitude[labels[f] * kValues + j] += std::abs(terms[j]);
    }
  }
  // The header's bound is (32 + chunks) * 2^-53 ~ 3.5e-12 for the largest cluster
  // (15,625 chunks); 1e-12 holds in practice, as the rounding errors do not all align.
  constexpr double kTolerance = 1e-12;
  double worst = 0;
  for (uint32_t c = 0; c < k; ++c) {
    const CvdSums& s = (*sums)[c];
    const double got[kValues] = {s.area, s.weighted_centroid.x, s.weighted_centroid.y,
                                 s.weighted_centroid.z, s.weighted_squared_norm};
    for (int j = 0; j < kValues; ++j) {
      const double want = reference[c * kValues + j].value();
      const double scale = magnitude[c * kValues + j];
      if (scale == 0) {
        EXPECT_EQ(got[j], 0.0) << "cluster " << c << " value " << j;
        continue;
      }
      const double error = std::abs(got[j] - want) / scale;
      worst = std::max(worst, error);
      EXPECT_LE(error, kTolerance) << "cluster " << c << " value " << j;
    }
  }
  std::printf("worst relative error (to the sum of |terms|): %.3g\n", worst);
  // The empty clusters are exactly zero.
  for (uint32_t c = 990; c < k; ++c) EXPECT_EQ((*sums)[c].area, 0.0);
}

}  // namespace
}  // namespace mlclust::gpu
