#include "core/mesh/mesh.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "tests/fixtures/test_meshes.h"

namespace mlclust {
namespace {

using testing::BowTie;
using testing::Grid;
using ::testing::HasSubstr;
using testing::MakeMesh;
using testing::Tetrahedron;
using testing::TwoTriangles;

TEST(FaceAdjacencyTest, TetrahedronIsClosedAndEveryFaceHasThreeNeighbours) {
  const TriangleMesh mesh = Tetrahedron();
  ASSERT_TRUE(ValidateMesh(mesh).ok());
  absl::StatusOr<FaceAdjacency> adjacency = BuildFaceAdjacency(mesh);
  ASSERT_TRUE(adjacency.ok()) << adjacency.status();
  for (uint32_t f = 0; f < 4; ++f) {
    std::vector<uint32_t> seen;
    for (FaceId g : adjacency->neighbours[f]) {
      ASSERT_TRUE(g.valid());
      EXPECT_NE(g.value(), f);
      seen.push_back(g.value());
    }
    std::sort(seen.begin(), seen.end());
    EXPECT_EQ(std::unique(seen.begin(), seen.end()), seen.end()) << "face " << f;
  }
  // Face 0 = (0, 2, 1): edge 0 is (0, 2), shared with face 3 = (0, 3, 2).
  EXPECT_EQ(adjacency->neighbours[0][0], FaceId(3));
  EXPECT_EQ(adjacency->neighbours[0][1], FaceId(2));  // edge (2, 1)
  EXPECT_EQ(adjacency->neighbours[0][2], FaceId(1));  // edge (1, 0)
}

TEST(FaceAdjacencyTest, TwoTrianglesShareOneEdgeAndHaveFourBoundaryEdges) {
  absl::StatusOr<FaceAdjacency> adjacency = BuildFaceAdjacency(TwoTriangles());
  ASSERT_TRUE(adjacency.ok());
  int boundary = 0;
  for (const auto& row : adjacency->neighbours) {
    for (FaceId g : row) boundary += !g.valid();
  }
  EXPECT_EQ(boundary, 4);
  EXPECT_EQ(adjacency->neighbours[0][1], FaceId(1));  // edge (1, 2)
  EXPECT_EQ(adjacency->neighbours[1][0], FaceId(0));  // edge (2, 1)
}

TEST(FaceAdjacencyTest, MeshWithAHoleHasTheHoleAsBoundary) {
  // 3 x 3 grid without the centre square: 16 faces, an outer and an inner boundary loop.
  const TriangleMesh mesh = Grid(3, {4});
  ASSERT_EQ(mesh.num_faces(), 16u);
  ASSERT_TRUE(ValidateMesh(mesh).ok()) << ValidateMesh(mesh);
  absl::StatusOr<FaceAdjacency> adjacency = BuildFaceAdjacency(mesh);
  ASSERT_TRUE(adjacency.ok());
  int boundary = 0;
  for (const auto& row : adjacency->neighbours) {
    for (FaceId g : row) boundary += !g.valid();
  }
  EXPECT_EQ(boundary, 12 + 4);  // outer loop of 12 edges, hole of 4
  EXPECT_EQ(CountFaceComponents(*adjacency), 1u);
}

TEST(FaceAdjacencyTest, NeighbourRelationIsSymmetricOnALargeGrid) {
  const TriangleMesh mesh = Grid(60);
  absl::StatusOr<FaceAdjacency> adjacency = BuildFaceAdjacency(mesh);
  ASSERT_TRUE(adjacency.ok());
  size_t interior_edges = 0;
  for (uint32_t f = 0; f < mesh.num_faces(); ++f) {
    for (FaceId g : adjacency->neighbours[f]) {
      if (!g.valid()) continue;
      ++interior_edges;
      const auto& back = adjacency->neighbours[g.value()];
      EXPECT_TRUE(back[0] == FaceId(f) || back[1] == FaceId(f) || back[2] == FaceId(f));
    }
  }
  // A 60 x 60 grid has 3 * 60 * 60 + 2 * 60 edges of which 4 * 60 are on the boundary.
  EXPECT_EQ(interior_edges / 2, 3u * 60 * 60 + 2 * 60 - 4 * 60);
}

TEST(ValidateMeshTest, AcceptsManifoldMeshes) {
  EXPECT_TRUE(ValidateMesh(Tetrahedron()).ok());
  EXPECT_TRUE(ValidateMesh(TwoTriangles()).ok());
  EXPECT_TRUE(ValidateMesh(Grid(5, {0, 7, 24})).ok());
}

TEST(ValidateMeshTest, RejectsEmptyMesh) {
  absl::Status status = ValidateMesh(TriangleMesh{});
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("empty mesh"));
}

TEST(ValidateMeshTest, RejectsIndexOutOfRangeNamingFaceAndCorner) {
  absl::Status status = ValidateMesh(MakeMesh({0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 1, 2, 0, 2, 7}));
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("face 1 corner 2: vertex index 7 is out of range"));
}

TEST(ValidateMeshTest, RejectsDegenerateFace) {
  absl::Status status = ValidateMesh(MakeMesh({0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 1, 2, 1, 1, 2}));
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("degenerate face 1"));
}

TEST(ValidateMeshTest, RejectsNonFiniteCoordinateNamingTheVertex) {
  TriangleMesh mesh = TwoTriangles();
  mesh.positions[3 * 3 + 1] = std::numeric_limits<float>::quiet_NaN();
  absl::Status status = ValidateMesh(mesh);
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("vertex 3 has a non-finite coordinate"));
  mesh.positions[3 * 3 + 1] = std::numeric_limits<float>::infinity();
  EXPECT_FALSE(ValidateMesh(mesh).ok());
}

TEST(ValidateMeshTest, RejectsNonManifoldEdgeNamingTheThreeFaces) {
  // Three triangles on the edge (0, 1): a fin.
  TriangleMesh mesh =
      MakeMesh({0, 0, 0, 1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1}, {0, 1, 2, 1, 0, 3, 0, 1, 4});
  absl::Status status = ValidateMesh(mesh);
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("non-manifold edge between vertices 0 and 1"));
  EXPECT_THAT(status.message(), HasSubstr("faces 0, 1 and 2"));
}

TEST(ValidateMeshTest, RejectsBowTieAsNonManifoldVertex) {
  absl::Status status = ValidateMesh(BowTie());
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("non-manifold vertex 0"));
  // Adjacency alone does not mind: no edge is shared by three faces.
  absl::StatusOr<FaceAdjacency> adjacency = BuildFaceAdjacency(BowTie());
  ASSERT_TRUE(adjacency.ok());
  EXPECT_EQ(CountFaceComponents(*adjacency), 2u);
}

TEST(ValidateMeshTest, RejectsPartialTriangles) {
  EXPECT_FALSE(ValidateMesh(MakeMesh({0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 1})).ok());
  EXPECT_FALSE(ValidateMesh(MakeMesh({0, 0, 0, 1, 0}, {0, 1, 2})).ok());
}

}  // namespace
}  // namespace mlclust
