// Repairing non-manifold meshes (--repair): bow-ties and edges of three or more faces are
// split by copying vertices, faces keep their ids, and the result passes ValidateMesh.
#include "core/mesh/repair.h"

#include <gtest/gtest.h>

#include <set>
#include <vector>

#include "core/io/mesh_io.h"
#include "tests/fixtures/test_meshes.h"

namespace mlclust {
namespace {

using testing::MakeMesh;

// Every face of `repaired` names the same positions, corner by corner, as in `input`.
void ExpectSameFacesAndPositions(const TriangleMesh& input, const TriangleMesh& repaired) {
  ASSERT_EQ(repaired.num_faces(), input.num_faces());
  for (size_t c = 0; c < input.indices.size(); ++c) {
    for (int j = 0; j < 3; ++j) {
      ASSERT_EQ(repaired.positions[3 * size_t{repaired.indices[c]} + j],
                input.positions[3 * size_t{input.indices[c]} + j])
          << "face " << c / 3 << " corner " << c % 3;
    }
  }
}

// Copies are appended; copy i repeats the position of the vertex it copies.
void ExpectCopiesAppended(const TriangleMesh& input, const MeshRepairResult& result) {
  const size_t n = input.num_vertices();
  ASSERT_EQ(result.mesh.num_vertices(), n + result.report.copy_of.size());
  for (size_t i = 0; i < n * 3; ++i) EXPECT_EQ(result.mesh.positions[i], input.positions[i]);
  for (size_t i = 0; i < result.report.copy_of.size(); ++i) {
    const uint32_t v = result.report.copy_of[i].value();
    for (int j = 0; j < 3; ++j) {
      EXPECT_EQ(result.mesh.positions[3 * (n + i) + j], input.positions[3 * size_t{v} + j]);
    }
  }
}

size_t BoundaryEdges(const TriangleMesh& mesh) {
  absl::StatusOr<FaceAdjacency> adjacency = BuildFaceAdjacency(mesh);
  EXPECT_TRUE(adjacency.ok());
  size_t boundary = 0;
  for (const auto& around : adjacency->neighbours) {
    for (FaceId f : around) boundary += !f.valid();
  }
  return boundary;
}

TEST(RepairTest, BowTieVertexBecomesTwo) {
  const TriangleMesh bow_tie = testing::BowTie();
  ASSERT_FALSE(ValidateMesh(bow_tie).ok());
  absl::StatusOr<MeshRepairResult> result = RepairNonManifold(bow_tie);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_TRUE(ValidateMesh(result->mesh).ok());
  EXPECT_TRUE(result->report.cut_edges.empty());
  ASSERT_EQ(result->report.split_vertices, std::vector<VertexId>{VertexId(0)});
  ASSERT_EQ(result->report.copy_of, std::vector<VertexId>{VertexId(0)});
  EXPECT_EQ(result->report.faces_changed, 1u);
  // Face 0 holds the lower corner of vertex 0, so it keeps vertex 0; face 1 gets the copy.
  const uint32_t copy = static_cast<uint32_t>(bow_tie.num_vertices());
  EXPECT_EQ(std::vector<uint32_t>(result->mesh.indices.begin(), result->mesh.indices.begin() + 3),
            std::vector<uint32_t>(bow_tie.indices.begin(), bow_tie.indices.begin() + 3));
  EXPECT_EQ(
      std::set<uint32_t>(result->mesh.indices.begin() + 3, result->mesh.indices.end()).count(copy),
      1u);
  ExpectSameFacesAndPositions(bow_tie, result->mesh);
  ExpectCopiesAppended(bow_tie, *result);
  EXPECT_EQ(result->report.Summary(),
            "split 1 vertex (0) into 2 copies, 1 face re-indexed; face "
            "ids unchanged");
}

// Three pages on one spine (vertices 0-1): the edge is cut and each page keeps its own
// copy of both spine vertices.
TEST(RepairTest, ThreeFacesOnAnEdgeBecomeThreeSheets) {
  const TriangleMesh book =
      MakeMesh({0, 0, 0, 0, 0, 1, 1, 0, 0, 0, 1, 0, -1, -1, 0}, {0, 1, 2, 1, 0, 3, 0, 1, 4});
  ASSERT_FALSE(ValidateMesh(book).ok());
  absl::StatusOr<MeshRepairResult> result = RepairNonManifold(book);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_TRUE(ValidateMesh(result->mesh).ok());
  ASSERT_EQ(result->report.cut_edges.size(), 1u);
  EXPECT_EQ(result->report.cut_edges[0].a, VertexId(0));
  EXPECT_EQ(result->report.cut_edges[0].b, VertexId(1));
  EXPECT_EQ(result->report.cut_edges[0].faces,
            (std::vector<FaceId>{FaceId(0), FaceId(1), FaceId(2)}));
  EXPECT_EQ(result->report.split_vertices, (std::vector<VertexId>{VertexId(0), VertexId(1)}));
  EXPECT_EQ(result->report.copy_of.size(), 4u);
  EXPECT_EQ(result->report.faces_changed, 2u);
  EXPECT_EQ(BoundaryEdges(result->mesh), 9u);  // three separate triangles
  ExpectSameFacesAndPositions(book, result->mesh);
  ExpectCopiesAppended(book, *result);
  EXPECT_NE(result->report.Summary().find("cut 1 non-manifold edge (vertices 0-1: faces 0, 1, 2)"),
            std::string::npos)
      << result->report.Summary();
}

// Two closed tetrahedra sharing one edge: four faces on it. Each tetrahedron keeps its
// own copy of the edge, which then borders its two faces again: two closed surfaces, no
// boundary, nothing cut further than needed.
TEST(RepairTest, TwoClosedSolidsOnOneEdgeStayClosed) {
  TriangleMesh mesh =
      MakeMesh({0, 0, 0, 0, 0, 1, 1, 0, 0.5f, 0.5f, 1, 0.5f, -1, 0, 0.5f, -0.5f, -1, 0.5f},
               {// tetrahedron 0, 1, 2, 3
                0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3,
                // tetrahedron 0, 1, 4, 5
                0, 4, 1, 0, 1, 5, 0, 5, 4, 1, 4, 5});
  ASSERT_FALSE(ValidateMesh(mesh).ok());
  absl::StatusOr<MeshRepairResult> result = RepairNonManifold(mesh);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_TRUE(ValidateMesh(result->mesh).ok());
  ASSERT_EQ(result->report.cut_edges.size(), 1u);
  EXPECT_EQ(result->report.cut_edges[0].faces.size(), 4u);
  EXPECT_EQ(result->report.copy_of, (std::vector<VertexId>{VertexId(0), VertexId(1)}));
  EXPECT_EQ(BoundaryEdges(result->mesh), 0u);
  absl::StatusOr<FaceAdjacency> adjacency = BuildFaceAdjacency(result->mesh);
  ASSERT_TRUE(adjacency.ok());
  EXPECT_EQ(CountFaceComponents(*adjacency), 2u);
  ExpectSameFacesAndPositions(mesh, result->mesh);
}

TEST(RepairTest, ManifoldMeshIsLeftAlone) {
  const TriangleMesh cube = testing::MakeCube(3).mesh;
  absl::StatusOr<MeshRepairResult> result = RepairNonManifold(cube);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_FALSE(result->report.changed());
  EXPECT_EQ(result->mesh.indices, cube.indices);
  EXPECT_EQ(result->mesh.positions, cube.positions);
  EXPECT_EQ(result->report.Summary(), "nothing to repair: the mesh is manifold");
}

TEST(RepairTest, RefusesWhatCannotBeRepairedInPlace) {
  EXPECT_NE(RepairNonManifold(MakeMesh({0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 1, 1}))
                .status()
                .message()
                .find("degenerate face 0"),
            std::string::npos);
  EXPECT_EQ(RepairNonManifold(MakeMesh({0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 1, 3})).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(RepairNonManifold(TriangleMesh{}).status().code(), absl::StatusCode::kInvalidArgument);
}

// A crop of CGAL's demo mesh polygon_mesh.off (libcgal-demo's data.tar.gz,
// data/meshes/polygon_mesh.off, 16,344 vertices, 32,245 faces): every face within two
// vertex rings of its non-manifold places (bench/experiments/crop_nonmanifold.py). The
// whole file's repair is in BENCHMARKS.md.
TEST(RepairTest, CgalPolygonMeshCrop) {
  absl::StatusOr<TriangleMesh> mesh =
      ReadMeshFile(std::string(MLCLUST_DATA_DIR) + "/../tests/fixtures/cgal_polygon_mesh_crop.off");
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  ASSERT_FALSE(ValidateMesh(*mesh).ok());
  absl::StatusOr<MeshRepairResult> result = RepairNonManifold(*mesh);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_TRUE(ValidateMesh(result->mesh).ok());
  // Its two non-manifold vertices (4113 and 4349 in the whole file) are vertices 3 and 10
  // here: five fans between them, so three copies; no edge has more than two faces.
  EXPECT_TRUE(result->report.cut_edges.empty());
  EXPECT_EQ(result->report.split_vertices, (std::vector<VertexId>{VertexId(3), VertexId(10)}));
  EXPECT_EQ(result->report.copy_of.size(), 3u);
  EXPECT_EQ(result->report.faces_changed, 6u);
  ExpectSameFacesAndPositions(*mesh, result->mesh);
  ExpectCopiesAppended(*mesh, *result);
  // Repairing the repaired mesh changes nothing.
  absl::StatusOr<MeshRepairResult> again = RepairNonManifold(result->mesh);
  ASSERT_TRUE(again.ok());
  EXPECT_FALSE(again->report.changed());
}

}  // namespace
}  // namespace mlclust
