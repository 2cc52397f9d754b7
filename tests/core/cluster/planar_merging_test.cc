// Planar Δ_merging (section 3.3.2, Fig. 3.17c): a cube cut into many planar pieces merges
// back into its six sides; a fold sharper than Δ stays; a slow bend does not chain.
#include "core/cluster/planar_merging.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <numbers>
#include <set>
#include <vector>

#include "tests/fixtures/labels.h"
#include "tests/fixtures/test_meshes.h"

namespace mlclust {
namespace {

using testing::MakeCube;
using testing::SubdividedCube;

using testing::DistinctLabels;

// A 6 x 6 cube: on sides 0-2 every square is a cluster, on sides 3-5 every triangle (labels
// spread out so that they are not face ids), 324 clusters in all.
std::vector<ClusterId> ManyPlanarPieces(const SubdividedCube& cube, int n) {
  std::vector<ClusterId> labels;
  for (size_t f = 0; f < cube.side.size(); ++f) {
    const uint32_t square = static_cast<uint32_t>(cube.square[f][0] * n + cube.square[f][1]);
    const uint32_t piece = cube.side[f] < 3 ? square : 100 + static_cast<uint32_t>(f);
    labels.push_back(ClusterId(1000 * static_cast<uint32_t>(cube.side[f]) + 7 * piece));
  }
  return labels;
}

TEST(PlanarMergingTest, CubeInManyPlanarPiecesMergesBackToItsSixSides) {
  const int n = 6;
  const SubdividedCube cube = MakeCube(n);
  const std::vector<ClusterId> labels = ManyPlanarPieces(cube, n);
  ASSERT_EQ(DistinctLabels(labels).size(), 3u * 36 + 3u * 72);
  PlanarMergingOptions options;
  options.max_angle_degrees = 1.0;
  absl::StatusOr<PlanarMergingResult> result = MergePlanarClusters(cube.mesh, labels, options);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_EQ(result->input_clusters, 324u);
  EXPECT_EQ(result->output_clusters, 6u);
  EXPECT_EQ(result->merges.size(), 318u);
  // Each side is one cluster, labelled with the smallest label on it.
  std::map<int, std::set<uint32_t>> per_side;
  std::map<int, uint32_t> smallest;
  for (size_t f = 0; f < labels.size(); ++f) {
    per_side[cube.side[f]].insert(result->labels[f].value());
    auto [it, inserted] = smallest.try_emplace(cube.side[f], labels[f].value());
    if (!inserted) it->second = std::min(it->second, labels[f].value());
  }
  for (int side = 0; side < 6; ++side) {
    ASSERT_EQ(per_side[side].size(), 1u) << "side " << side;
    EXPECT_EQ(*per_side[side].begin(), smallest[side]) << "side " << side;
  }
  for (const PlanarMerge& merge : result->merges) {
    EXPECT_LT(merge.kept, merge.absorbed);
    EXPECT_LT(merge.angle_degrees, 1e-4);
  }
  // Sides meet at 90 degrees: just below that nothing more merges.
  options.max_angle_degrees = 89.9;
  result = MergePlanarClusters(cube.mesh, labels, options);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_EQ(result->output_clusters, 6u);
}

TEST(PlanarMergingTest, ZeroAngleMergesNothing) {
  const SubdividedCube cube = MakeCube(3);
  const std::vector<ClusterId> labels = ManyPlanarPieces(cube, 3);
  PlanarMergingOptions options;
  options.max_angle_degrees = 0;
  absl::StatusOr<PlanarMergingResult> result = MergePlanarClusters(cube.mesh, labels, options);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_EQ(result->labels, labels);
  EXPECT_TRUE(result->merges.empty());
  EXPECT_EQ(result->output_clusters, result->input_clusters);
}

// A strip of `panels` flat quads (two triangles each) along y, each turned by `step`
// degrees about the x axis from the one before: a slow bend. Panel i is faces 2i, 2i + 1.
TriangleMesh BentStrip(int panels, double step_degrees) {
  TriangleMesh mesh;
  double y = 0, z = 0;
  for (int row = 0; row <= panels; ++row) {
    for (float x : {0.f, 1.f}) {
      mesh.positions.insert(mesh.positions.end(),
                            {x, static_cast<float>(y), static_cast<float>(z)});
    }
    const double angle = row * step_degrees * std::numbers::pi / 180;
    y += std::cos(angle);
    z += std::sin(angle);
  }
  for (uint32_t i = 0; i < static_cast<uint32_t>(panels); ++i) {
    const uint32_t a = 2 * i, b = 2 * i + 1, c = 2 * i + 3, d = 2 * i + 2;
    mesh.indices.insert(mesh.indices.end(), {a, b, c, a, c, d});
  }
  return mesh;
}

// Neighbouring panels differ by 0.8 degrees, under Δ = 1. Merging all such pairs (a
// transitive closure) would make the strip one cluster, 15 degrees from end to end. With
// the merged normal recomputed, a merged pair sits 1.2 degrees from the next panel, so no
// cluster grows past two panels.
TEST(PlanarMergingTest, SlowBendDoesNotChainIntoOneCluster) {
  const int panels = 20;
  const TriangleMesh strip = BentStrip(panels, 0.8);
  ASSERT_TRUE(ValidateMesh(strip).ok());
  std::vector<ClusterId> labels;
  for (int f = 0; f < 2 * panels; ++f) labels.push_back(ClusterId(f / 2));
  PlanarMergingOptions options;
  options.max_angle_degrees = 1.0;
  absl::StatusOr<PlanarMergingResult> result = MergePlanarClusters(strip, labels, options);
  ASSERT_TRUE(result.ok()) << result.status();
  std::map<uint32_t, int> faces_per_cluster;
  for (ClusterId l : result->labels) ++faces_per_cluster[l.value()];
  for (auto [label, faces] : faces_per_cluster) EXPECT_LE(faces, 4) << "cluster " << label;
  EXPECT_GE(result->output_clusters, 10u);
  EXPECT_LT(result->output_clusters, 20u);
  for (const PlanarMerge& merge : result->merges) {
    EXPECT_NEAR(merge.angle_degrees, 0.8, 1e-3);
  }
  // At 2 degrees the pairs (1.6 degrees apart) merge further.
  options.max_angle_degrees = 2.0;
  result = MergePlanarClusters(strip, labels, options);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_LT(result->output_clusters, 10u);
}

// A cluster whose faces all have density 0 has no representative normal (eq. 3.37's sum is
// zero) and merges with nothing.
TEST(PlanarMergingTest, DensityWeightsTheNormals) {
  const SubdividedCube cube = MakeCube(2);
  std::vector<ClusterId> labels;
  std::vector<double> density;
  for (size_t f = 0; f < cube.side.size(); ++f) {
    labels.push_back(ClusterId(static_cast<uint32_t>(2 * cube.side[f] + cube.square[f][0])));
    density.push_back(cube.side[f] == 2 ? 0.0 : 1.0);
  }
  PlanarMergingOptions options;
  options.face_density = density;
  absl::StatusOr<PlanarMergingResult> result = MergePlanarClusters(cube.mesh, labels, options);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_EQ(result->input_clusters, 12u);
  EXPECT_EQ(result->output_clusters, 7u);
}

TEST(PlanarMergingTest, RefusesBadInput) {
  const SubdividedCube cube = MakeCube(2);
  std::vector<ClusterId> labels(cube.side.size(), ClusterId(0));
  PlanarMergingOptions options;
  EXPECT_NE(MergePlanarClusters(cube.mesh, std::span(labels).first(3), options)
                .status()
                .message()
                .find("'labels'"),
            std::string::npos);
  labels[4] = ClusterId::Invalid();
  EXPECT_NE(MergePlanarClusters(cube.mesh, labels, options).status().message().find("'labels'"),
            std::string::npos);
  labels[4] = ClusterId(0);
  for (double angle : {-1.0, 181.0, std::nan("")}) {
    options.max_angle_degrees = angle;
    EXPECT_NE(MergePlanarClusters(cube.mesh, labels, options)
                  .status()
                  .message()
                  .find("'max_angle_degrees'"),
              std::string::npos);
  }
  options.max_angle_degrees = 1;
  std::vector<double> density(labels.size(), 1.0);
  density[2] = -1;
  options.face_density = density;
  EXPECT_NE(
      MergePlanarClusters(cube.mesh, labels, options).status().message().find("'face_density'"),
      std::string::npos);
  options.face_density = {};
  const TriangleMesh bow_tie = testing::BowTie();
  std::vector<ClusterId> two(2, ClusterId(0));
  EXPECT_EQ(MergePlanarClusters(bow_tie, two, options).status().code(),
            absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace mlclust
