// Partition (core/cluster/partition.h): labels plus per-cluster sums, sizes and energies,
// kept exact under Move and Merge.
#include "core/cluster/partition.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "core/energy/energies.h"
#include "tests/fixtures/test_meshes.h"

namespace mlclust {
namespace {

// A 4 x 4 grid (32 faces) in the z = 0 plane; unit squares of two triangles each.
const testing::LoadedMesh& GridMesh() {
  static const auto* grid = new testing::LoadedMesh(testing::Load(testing::Grid(4)));
  return *grid;
}

// The CVD sums of the given faces, added directly.
CvdSums DirectSums(const CvdEnergy& energy, const std::vector<uint32_t>& labels, uint32_t cluster) {
  CvdSums sums;
  for (uint32_t f = 0; f < labels.size(); ++f) {
    if (labels[f] == cluster) sums += energy.face_sums(f);
  }
  return sums;
}

void ExpectConsistent(const Partition<CvdEnergy>& partition, const CvdEnergy& energy) {
  const std::vector<uint32_t> labels(partition.labels().begin(), partition.labels().end());
  uint32_t non_empty = 0;
  double total = 0;
  for (uint32_t c = 0; c < partition.capacity(); ++c) {
    const CvdSums direct = DirectSums(energy, labels, c);
    uint32_t size = 0;
    for (uint32_t l : labels) size += l == c;
    EXPECT_EQ(partition.size(c), size) << c;
    EXPECT_NEAR(partition.sums(c).area, direct.area, 1e-12) << c;
    EXPECT_NEAR(partition.sums(c).weighted_squared_norm, direct.weighted_squared_norm, 1e-9);
    const double expected = size > 0 ? energy.Energy(direct) : 0.0;
    EXPECT_NEAR(partition.cluster_energy(c), expected, 1e-9) << c;
    non_empty += size > 0;
    total += expected;
  }
  EXPECT_EQ(partition.num_clusters(), non_empty);
  EXPECT_NEAR(partition.TotalEnergy(), total, 1e-9);
}

TEST(PartitionTest, BuildsSumsSizesAndEnergiesFromTheLabels) {
  const testing::LoadedMesh& l = GridMesh();
  const CvdEnergy energy(l.measures);
  // Left and right halves, and an id (2) with no face: capacity 3, two clusters.
  std::vector<uint32_t> labels(32);
  for (uint32_t f = 0; f < 32; ++f) labels[f] = (f / 2) % 4 < 2 ? 0 : 1;
  const Partition<CvdEnergy> partition(energy, labels, 3);
  EXPECT_EQ(partition.capacity(), 3u);
  EXPECT_EQ(partition.num_clusters(), 2u);
  EXPECT_EQ(partition.size(0), 16u);
  EXPECT_EQ(partition.size(1), 16u);
  EXPECT_EQ(partition.size(2), 0u);
  EXPECT_DOUBLE_EQ(partition.sums(0).area, 8.0);  // a 2 x 4 rectangle
  EXPECT_EQ(partition.cluster_energy(2), 0.0);
  ExpectConsistent(partition, energy);
  // The total is the energy of the labels computed from scratch.
  std::vector<ClusterId> ids;
  for (uint32_t c : labels) ids.push_back(ClusterId(c));
  EXPECT_NEAR(partition.TotalEnergy(), MeshEnergyOfLabels({}, l.mesh, ids), 1e-9);
}

TEST(PartitionTest, MoveUpdatesBothClustersAndCountsEmptiedAndFilledOnes) {
  const testing::LoadedMesh& l = GridMesh();
  const CvdEnergy energy(l.measures);
  std::vector<uint32_t> labels(32, 0);
  labels[0] = 1;
  Partition<CvdEnergy> partition(energy, labels, 3);
  EXPECT_EQ(partition.num_clusters(), 2u);
  partition.Move(5, 2);  // fills cluster 2
  EXPECT_EQ(partition.label(5), 2u);
  EXPECT_EQ(partition.num_clusters(), 3u);
  ExpectConsistent(partition, energy);
  partition.Move(0, 0);  // empties cluster 1
  EXPECT_EQ(partition.num_clusters(), 2u);
  EXPECT_EQ(partition.size(1), 0u);
  // An emptied cluster keeps no rounding residue.
  EXPECT_EQ(partition.sums(1).area, 0.0);
  EXPECT_EQ(partition.sums(1).weighted_squared_norm, 0.0);
  EXPECT_EQ(partition.cluster_energy(1), 0.0);
  ExpectConsistent(partition, energy);
  // Many moves back and forth stay exact enough.
  for (int round = 0; round < 50; ++round) {
    for (uint32_t f = 0; f < 32; f += 3) partition.Move(f, (partition.label(f) + 1) % 3);
  }
  ExpectConsistent(partition, energy);
}

TEST(PartitionTest, MergeMovesEveryFaceOfTheGoneCluster) {
  const testing::LoadedMesh& l = GridMesh();
  const CvdEnergy energy(l.measures);
  std::vector<uint32_t> labels(32);
  for (uint32_t f = 0; f < 32; ++f) labels[f] = f / 8;  // four rows of the grid
  Partition<CvdEnergy> partition(energy, labels, 4);
  std::vector<uint32_t> row_two;
  for (uint32_t f = 16; f < 24; ++f) row_two.push_back(f);
  partition.Merge(1, 2, row_two);
  EXPECT_EQ(partition.num_clusters(), 3u);
  EXPECT_EQ(partition.size(1), 16u);
  EXPECT_EQ(partition.size(2), 0u);
  for (uint32_t f : row_two) EXPECT_EQ(partition.label(f), 1u);
  ExpectConsistent(partition, energy);
}

// Issue 26 item 7: a face's sums leave a cluster by subtraction, which loses what it cancels.
// mwcvd-max with densities 1e-4 (rho^10 = 1e-40) on 31 faces and 10 (rho^10 = 1e10) on one:
// the cluster's sum of rho^10 rounds to 1e10, so removing that face leaves exactly 0 instead
// of 30e-40, and the weight (sum rho^10)^(1/10) is 0 instead of about 1.4e-4. RefreshAllSums
// gives every cluster the sums of its faces again.
TEST(PartitionTest, RefreshAllSumsGivesBackWhatASubtractionLost) {
  const testing::LoadedMesh& l = GridMesh();
  std::vector<double> density(32, 1e-4);
  density[5] = 10;
  const MwcvdEnergy energy(l.measures, density, MwcvdEnergy::Weight::kMax);
  std::vector<uint32_t> labels(32, 0);
  labels[31] = 1;
  Partition<MwcvdEnergy> partition(energy, labels, 2);
  partition.Move(5, 1);
  EXPECT_EQ(partition.sums(0).density_power, 0.0);  // the subtraction's loss
  EXPECT_EQ(partition.cluster_energy(0), 0.0);
  partition.RefreshAllSums();
  const double power = 30 * std::pow(1e-4, 10);
  EXPECT_NEAR(partition.sums(0).density_power, power, 1e-12 * power);
  const double weight = std::pow(power, 0.1);
  EXPECT_NEAR(energy.ClusterWeight(partition.sums(0)), weight, 1e-12 * weight);
  EXPECT_DOUBLE_EQ(partition.cluster_energy(0), energy.Energy(partition.sums(0)));
  EXPECT_GT(partition.cluster_energy(0), 0.0);
  EXPECT_DOUBLE_EQ(partition.sums(1).density_power, std::pow(1e-4, 10) + 1e10);
  EXPECT_EQ(partition.size(0), 30u);
  EXPECT_EQ(partition.size(1), 2u);
}

}  // namespace
}  // namespace mlclust
