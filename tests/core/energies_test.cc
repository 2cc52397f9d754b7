#include "core/cvd_energy.h"

#include <gtest/gtest.h>

#include <random>

#include "core/face_measures.h"
#include "core/mesh_io.h"
#include "tests/core/test_meshes.h"

namespace mlclust {
namespace {

TEST(FaceMeasuresTest, UnitSquareTriangles) {
  const FaceMeasures m = ComputeFaceMeasures(testing::TwoTriangles());
  ASSERT_EQ(m.num_faces(), 2u);
  EXPECT_DOUBLE_EQ(m.area[0], 0.5);
  EXPECT_DOUBLE_EQ(m.area[1], 0.5);
  EXPECT_DOUBLE_EQ(m.centroid[0].x, 1.0 / 3);
  EXPECT_DOUBLE_EQ(m.centroid[1].y, 2.0 / 3);
  EXPECT_DOUBLE_EQ(m.unit_normal[0].z, 1.0);
  EXPECT_DOUBLE_EQ(m.unit_normal[1].z, 1.0);
}

// Sums per cluster from the labels, then energy from sums (eq. 3.7).
double EnergyFromSums(const FaceMeasures& m, const std::vector<ClusterId>& labels, Vec3 origin) {
  std::map<uint32_t, CvdSums> sums;
  for (size_t j = 0; j < labels.size(); ++j) {
    sums[labels[j].value()] += CvdFaceSums(m.area[j], m.centroid[j], origin);
  }
  double energy = 0;
  for (const auto& [id, s] : sums) energy += CvdEnergy(s);
  return energy;
}

std::vector<ClusterId> RandomLabels(size_t n, uint32_t k, uint32_t seed) {
  std::mt19937 rng(seed);
  std::vector<ClusterId> labels(n);
  for (auto& l : labels) l = ClusterId(rng() % k);
  return labels;
}

TEST(CvdEnergyTest, IncrementalEqualsDirectSumOnARealMesh) {
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(testing::DataPath("fandisk.off"));
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  const FaceMeasures m = ComputeFaceMeasures(*mesh);
  for (uint32_t k : {1u, 7u, 100u, 5000u}) {
    const std::vector<ClusterId> labels = RandomLabels(m.num_faces(), k, k);
    const double direct = CvdEnergyDirect(m, labels);
    ASSERT_GT(direct, 0);
    // With the origin near the mesh and far from it: the centred form must stay exact.
    EXPECT_NEAR(EnergyFromSums(m, labels, m.centroid[0]), direct, 1e-10 * direct) << k;
    EXPECT_NEAR(EnergyFromSums(m, labels, Vec3{}), direct, 1e-8 * direct) << k;
  }
}

TEST(CvdEnergyTest, MergeCostEqualsEnergyDifference) {
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(testing::DataPath("elephant.off"));
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  const FaceMeasures m = ComputeFaceMeasures(*mesh);
  std::mt19937 rng(3);
  for (int trial = 0; trial < 50; ++trial) {
    CvdSums a, b;
    for (size_t j = 0; j < m.num_faces(); ++j) {
      const uint32_t r = rng() % 10;
      if (r == 0) a += CvdFaceSums(m.area[j], m.centroid[j], m.centroid[0]);
      if (r == 1) b += CvdFaceSums(m.area[j], m.centroid[j], m.centroid[0]);
    }
    const double difference = CvdEnergy(a + b) - CvdEnergy(a) - CvdEnergy(b);
    EXPECT_NEAR(CvdMergeCost(a, b), difference, 1e-9 * CvdEnergy(a + b));
    EXPECT_GE(CvdMergeCost(a, b), 0);
  }
}

TEST(CvdEnergyTest, SingleFaceAndZeroAreaClustersHaveNoEnergy) {
  const CvdSums face = CvdFaceSums(2.0, {1, 2, 3}, {0, 0, 0});
  EXPECT_NEAR(CvdEnergy(face), 0, 1e-12);
  const CvdSums empty = CvdFaceSums(0.0, {5, 5, 5}, {0, 0, 0});
  EXPECT_EQ(CvdEnergy(empty), 0);
  EXPECT_EQ(CvdMergeCost(face, empty), 0);
  // Two unit-area faces two apart: cost = (1 * 1 / 2) * 4 = 2.
  EXPECT_DOUBLE_EQ(CvdMergeCost(CvdFaceSums(1, {0, 0, 0}, {}), CvdFaceSums(1, {2, 0, 0}, {})), 2.0);
}

}  // namespace
}  // namespace mlclust
