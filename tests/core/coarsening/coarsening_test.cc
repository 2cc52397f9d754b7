#include "core/coarsening/coarsening.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <map>
#include <numbers>
#include <random>
#include <set>

#include "absl/container/flat_hash_map.h"
#include "absl/container/flat_hash_set.h"
#include "absl/strings/str_cat.h"
#include "core/cluster/multilevel.h"
#include "core/energy/energies.h"
#include "core/hierarchy/hierarchy.h"
#include "core/io/mesh_io.h"
#include "core/mesh/face_measures.h"
#include "tests/fixtures/labels.h"
#include "tests/fixtures/test_meshes.h"

namespace mlclust {
namespace {

using ::testing::HasSubstr;

struct Prepared {
  TriangleMesh mesh;
  FaceAdjacency adjacency;
};

Prepared Prepare(TriangleMesh mesh) {
  Prepared p;
  p.mesh = std::move(mesh);
  EXPECT_TRUE(ValidateMesh(p.mesh).ok()) << ValidateMesh(p.mesh);
  p.adjacency = *BuildFaceAdjacency(p.mesh);
  return p;
}

using testing::AsLabels;

using testing::MakeCube;
using testing::SubdividedCube;

// A torus of n x m squares (two triangles each), consistently oriented.
TriangleMesh MakeTorus(int n, int m) {
  TriangleMesh mesh;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < m; ++j) {
      const double u = 2 * std::numbers::pi * i / n, v = 2 * std::numbers::pi * j / m;
      mesh.positions.insert(
          mesh.positions.end(),
          {static_cast<float>((2 + std::cos(v)) * std::cos(u)),
           static_cast<float>((2 + std::cos(v)) * std::sin(u)), static_cast<float>(std::sin(v))});
    }
  }
  auto at = [&](int i, int j) { return static_cast<uint32_t>((i % n) * m + (j % m)); };
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < m; ++j) {
      mesh.indices.insert(mesh.indices.end(), {at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j),
                                               at(i + 1, j + 1), at(i, j + 1)});
    }
  }
  return mesh;
}

// A graph Voronoi partition: k clusters grown from k seed faces (picked at random with a
// fixed seed) by simultaneous breadth-first search over the face adjacency. Clusters are
// connected; on a fine mesh they are disc-like. Labels are the seeds' face ids.
std::vector<ClusterId> GrowClusters(const FaceAdjacency& adjacency, size_t k, uint32_t seed) {
  const size_t n = adjacency.num_faces();
  std::vector<ClusterId> labels(n, ClusterId::Invalid());
  std::mt19937 random(seed);
  std::vector<uint32_t> queue;
  while (queue.size() < k) {
    const uint32_t face = std::uniform_int_distribution<uint32_t>(0, n - 1)(random);
    if (labels[face].valid()) continue;
    labels[face] = ClusterId(face);
    queue.push_back(face);
  }
  for (size_t head = 0; head < queue.size(); ++head) {
    const uint32_t face = queue[head];
    for (FaceId neighbour : adjacency.neighbours[face]) {
      if (neighbour.valid() && !labels[neighbour.value()].valid()) {
        labels[neighbour.value()] = labels[face];
        queue.push_back(neighbour.value());
      }
    }
  }
  return labels;
}

// The CVD clustering with k clusters that HC finds (k >= the number of components).
std::vector<ClusterId> HcClusters(const Prepared& p, uint32_t k) {
  HierarchyLog log;
  const FaceMeasures measures = ComputeFaceMeasures(p.mesh);
  MultilevelOptions options;
  options.optimizer = MultilevelOptions::Optimizer::kNone;  // HC
  options.min_clusters = k;
  auto summary = RunMultilevel({&p.mesh, &p.adjacency, &measures, {}}, options, log);
  EXPECT_TRUE(summary.ok()) << summary.status();
  return *log.LabelsAt(log.num_levels() - 1);
}

size_t CountDistinct(const std::vector<ClusterId>& labels) {
  return absl::flat_hash_set<ClusterId>(labels.begin(), labels.end()).size();
}

// V - E + F over the used vertices, and the number of boundary edges.
struct Topology {
  int64_t euler = 0;
  int64_t boundary_edges = 0;
};

Topology TopologyOf(const TriangleMesh& mesh) {
  absl::flat_hash_set<uint32_t> used(mesh.indices.begin(), mesh.indices.end());
  absl::flat_hash_map<uint64_t, int> undirected;
  for (size_t f = 0; f < mesh.num_faces(); ++f) {
    for (int i = 0; i < 3; ++i) {
      const uint64_t a = mesh.indices[3 * f + i], b = mesh.indices[3 * f + (i + 1) % 3];
      ++undirected[a < b ? (a << 32 | b) : (b << 32 | a)];
    }
  }
  Topology t;
  for (const auto& [edge, count] : undirected) t.boundary_edges += count == 1;
  t.euler = static_cast<int64_t>(used.size()) - static_cast<int64_t>(undirected.size()) +
            static_cast<int64_t>(mesh.num_faces());
  return t;
}

// Checks what CoarsenMesh promises: a valid mesh with exactly k vertices, all used, every
// directed edge once, every edge bordering one or two triangles (two everywhere if
// `closed`), one fan per vertex (ValidateMesh).
void ExpectValidCoarseMesh(const TriangleMesh& coarse, size_t k, bool closed) {
  EXPECT_TRUE(ValidateMesh(coarse).ok()) << ValidateMesh(coarse);
  EXPECT_EQ(coarse.num_vertices(), k);
  absl::flat_hash_set<uint32_t> used(coarse.indices.begin(), coarse.indices.end());
  EXPECT_EQ(used.size(), k);
  absl::flat_hash_set<uint64_t> directed;
  for (size_t f = 0; f < coarse.num_faces(); ++f) {
    for (int i = 0; i < 3; ++i) {
      const uint64_t a = coarse.indices[3 * f + i], b = coarse.indices[3 * f + (i + 1) % 3];
      EXPECT_TRUE(directed.insert(a << 32 | b).second) << "directed edge " << a << " -> " << b;
    }
  }
  if (closed) {
    for (uint64_t edge : directed) {
      EXPECT_TRUE(directed.contains((edge & 0xffffffffu) << 32 | edge >> 32))
          << "edge " << (edge >> 32) << " - " << (edge & 0xffffffffu) << " has one triangle";
    }
  }
}

// Signed volume (times 6) of a closed mesh: positive when its faces point outwards.
double SignedVolume(const TriangleMesh& mesh) {
  double volume = 0;
  for (size_t f = 0; f < mesh.num_faces(); ++f) {
    const FaceId face(static_cast<uint32_t>(f));
    volume += Dot(mesh.position(mesh.corner(face, 0)),
                  Cross(mesh.position(mesh.corner(face, 1)), mesh.position(mesh.corner(face, 2))));
  }
  return volume;
}

double PlaneDistance(const Vec3& point, const Vec3& normal, const Vec3& on_plane) {
  return Dot(point - on_plane, normal) / Norm(normal);
}

TEST(CoarseningTest, TetrahedronWithOneClusterPerFaceGivesItsDual) {
  const Prepared p = Prepare(testing::Tetrahedron());
  const std::vector<ClusterId> labels = AsLabels({7, 5, 9, 3});
  absl::StatusOr<TriangleMesh> coarse = CoarsenMesh(p.mesh, p.adjacency, labels);
  ASSERT_TRUE(coarse.ok()) << coarse.status();
  ExpectValidCoarseMesh(*coarse, 4, /*closed=*/true);
  EXPECT_EQ(coarse->num_faces(), 4u);
  EXPECT_EQ(TopologyOf(*coarse).euler, 2);
  EXPECT_GT(SignedVolume(*coarse), 0);
  // Vertex i is the i-th label seen, at its face's centroid.
  EXPECT_EQ(CoarseVertexClusters(labels), labels);
  const FaceMeasures measures = ComputeFaceMeasures(p.mesh);
  for (uint32_t v = 0; v < 4; ++v) {
    const Vec3 position = coarse->position(VertexId(v));
    EXPECT_NEAR(Norm(position - measures.centroid[v]), 0, 1e-7) << v;
  }
}

TEST(CoarseningTest, ThreeClustersOnASphereGiveATwoTrianglePillow) {
  const Prepared p = Prepare(testing::Tetrahedron());
  absl::StatusOr<TriangleMesh> coarse = CoarsenMesh(p.mesh, p.adjacency, AsLabels({0, 1, 2, 2}));
  ASSERT_TRUE(coarse.ok()) << coarse.status();
  ExpectValidCoarseMesh(*coarse, 3, /*closed=*/true);
  ASSERT_EQ(coarse->num_faces(), 2u);  // (0, 1, 2) and (0, 2, 1): the same clusters, both ways
  EXPECT_EQ(TopologyOf(*coarse).euler, 2);
}

TEST(CoarseningTest, CubeWithOneClusterPerSideGivesAnOctahedron) {
  const SubdividedCube cube = MakeCube(1);
  const Prepared p = Prepare(cube.mesh);
  std::vector<ClusterId> labels;
  for (int side : cube.side) labels.push_back(ClusterId(side));
  for (auto placement :
       {CoarseningOptions::Placement::kCentroid, CoarseningOptions::Placement::kQuadric}) {
    absl::StatusOr<TriangleMesh> coarse =
        CoarsenMesh(p.mesh, p.adjacency, labels, {.placement = placement});
    ASSERT_TRUE(coarse.ok()) << coarse.status();
    ExpectValidCoarseMesh(*coarse, 6, /*closed=*/true);
    EXPECT_EQ(coarse->num_faces(), 8u);  // one per cube corner
    EXPECT_EQ(TopologyOf(*coarse).euler, 2);
    // Vertex s is the centre of side s: +-0.5 on its axis, 0 elsewhere.
    for (int side = 0; side < 6; ++side) {
      const Vec3 position = coarse->position(VertexId(side));
      const double coordinate[3] = {position.x, position.y, position.z};
      for (int axis = 0; axis < 3; ++axis) {
        const double want = axis == side % 3 ? (side < 3 ? 0.5 : -0.5) : 0.0;
        EXPECT_NEAR(coordinate[axis], want, 1e-7) << side << " " << axis;
      }
    }
    // Each triangle is a corner: one side of each axis, outward.
    for (size_t f = 0; f < coarse->num_faces(); ++f) {
      std::array<int, 3> axes;
      for (int i = 0; i < 3; ++i) axes[i] = static_cast<int>(coarse->indices[3 * f + i]) % 3;
      std::sort(axes.begin(), axes.end());
      EXPECT_EQ(axes, (std::array<int, 3>{0, 1, 2}));
    }
    EXPECT_NEAR(SignedVolume(*coarse), 1.0, 1e-6);  // 6 x the octahedron's (4/3) 0.5^3
  }
}

// Eight clusters on MakeCube(2), one per cube corner (its three quarter-sides): corner
// (x, y, z), each 0 or 1, is cluster 4x + 2y + z.
std::vector<ClusterId> CornerClusters(const SubdividedCube& cube) {
  std::vector<ClusterId> labels;
  for (size_t f = 0; f < cube.side.size(); ++f) {
    const int side = cube.side[f], a = side % 3, u = (a + 1) % 3, w = (a + 2) % 3;
    std::array<int, 3> corner;
    corner[a] = side < 3 ? 1 : 0;
    corner[u] = cube.square[f][0];
    corner[w] = cube.square[f][1];
    labels.push_back(ClusterId(corner[0] * 4 + corner[1] * 2 + corner[2]));
  }
  return labels;
}

TEST(CoarseningTest, QuadricPutsACornerClusterOnTheCornerAndTheCentroidInside) {
  // Eight clusters, one per cube corner (its three quarter-sides): the coarse mesh is a cube
  // (12 triangles, two per side's four-cluster corner at the side's centre).
  const SubdividedCube cube = MakeCube(2);
  const Prepared p = Prepare(cube.mesh);
  const std::vector<ClusterId> labels = CornerClusters(cube);
  const std::vector<ClusterId> clusters = CoarseVertexClusters(labels);
  ASSERT_EQ(clusters.size(), 8u);

  absl::StatusOr<TriangleMesh> quadric = CoarsenMesh(
      p.mesh, p.adjacency, labels, {.placement = CoarseningOptions::Placement::kQuadric});
  ASSERT_TRUE(quadric.ok()) << quadric.status();
  ExpectValidCoarseMesh(*quadric, 8, /*closed=*/true);
  EXPECT_EQ(quadric->num_faces(), 12u);
  EXPECT_EQ(TopologyOf(*quadric).euler, 2);
  EXPECT_NEAR(SignedVolume(*quadric), 6.0, 1e-5);  // 6 x the unit cube's volume
  for (uint32_t v = 0; v < 8; ++v) {
    const uint32_t c = clusters[v].value();
    const Vec3 corner{(c >> 2 & 1) - 0.5, (c >> 1 & 1) - 0.5, (c & 1) - 0.5};
    EXPECT_NEAR(Norm(quadric->position(VertexId(v)) - corner), 0, 1e-6) << c;
  }

  absl::StatusOr<TriangleMesh> centroid = CoarsenMesh(p.mesh, p.adjacency, labels);
  ASSERT_TRUE(centroid.ok()) << centroid.status();
  for (uint32_t v = 0; v < 8; ++v) {
    // The centroid of three quarter-sides of corner (1/2, 1/2, 1/2): (1/2, 1/4, 1/4) and
    // its permutations averaged, i.e. 1/3 on each axis.
    const Vec3 position = centroid->position(VertexId(v));
    EXPECT_NEAR(std::abs(position.x), 1.0 / 3, 1e-6);
    EXPECT_NEAR(std::abs(position.y), 1.0 / 3, 1e-6);
    EXPECT_NEAR(std::abs(position.z), 1.0 / 3, 1e-6);
  }
}

// Rotates every position by a fixed rotation (axis (1, 2, 3), 0.7 rad).
void Rotate(TriangleMesh& mesh) {
  const Vec3 axis = Vec3{1, 2, 3} / Norm(Vec3{1, 2, 3});
  const double c = std::cos(0.7), s = std::sin(0.7);
  for (size_t v = 0; v < mesh.num_vertices(); ++v) {
    const Vec3 p = mesh.position(VertexId(static_cast<uint32_t>(v)));
    const Vec3 r = p * c + Cross(axis, p) * s + axis * (Dot(axis, p) * (1 - c));
    mesh.positions[3 * v] = static_cast<float>(r.x);
    mesh.positions[3 * v + 1] = static_cast<float>(r.y);
    mesh.positions[3 * v + 2] = static_cast<float>(r.z);
  }
}

TEST(CoarseningTest, QuadricVertexOfAPlanarClusterLiesOnItsPlane) {
  // A rotated cube, 3 x 3 squares per side, one cluster per side: every cluster is planar,
  // so its quadric has rank one and the minimiser must stay on the plane.
  SubdividedCube cube = MakeCube(3);
  Rotate(cube.mesh);
  const Prepared p = Prepare(cube.mesh);
  std::vector<ClusterId> labels;
  for (int side : cube.side) labels.push_back(ClusterId(side));
  absl::StatusOr<TriangleMesh> coarse = CoarsenMesh(
      p.mesh, p.adjacency, labels, {.placement = CoarseningOptions::Placement::kQuadric});
  ASSERT_TRUE(coarse.ok()) << coarse.status();
  ExpectValidCoarseMesh(*coarse, 6, /*closed=*/true);
  const FaceMeasures measures = ComputeFaceMeasures(p.mesh);
  for (size_t f = 0; f < labels.size(); ++f) {
    const Vec3 vertex = coarse->position(VertexId(labels[f].value()));
    EXPECT_NEAR(PlaneDistance(vertex, measures.unit_normal[f], measures.centroid[f]), 0, 1e-6);
  }
}

TEST(CoarseningTest, QuadricVertexOfAnEdgeClusterLiesOnTheEdge) {
  // The corner clusters of the test above, with corners (1, 1, 0) and (1, 1, 1) merged: the
  // halves of the +x and +y sides along the cube edge x = y = 0.5 and a quarter of each of
  // the +z and -z sides. Its quadric is 0.5 (x - 0.5)^2 + 0.5 (y - 0.5)^2 + 0.25 (z - 0.5)^2
  // + 0.25 (z + 0.5)^2, least at (0.5, 0.5, 0) on the edge.
  const SubdividedCube cube = MakeCube(2);
  const Prepared p = Prepare(cube.mesh);
  std::vector<ClusterId> labels = CornerClusters(cube);
  for (ClusterId& label : labels) {
    if (label == ClusterId(7)) label = ClusterId(6);
  }
  absl::StatusOr<TriangleMesh> coarse = CoarsenMesh(
      p.mesh, p.adjacency, labels, {.placement = CoarseningOptions::Placement::kQuadric});
  ASSERT_TRUE(coarse.ok()) << coarse.status();
  ExpectValidCoarseMesh(*coarse, 7, /*closed=*/true);
  const std::vector<ClusterId> clusters = CoarseVertexClusters(labels);
  const uint32_t merged = static_cast<uint32_t>(
      std::find(clusters.begin(), clusters.end(), ClusterId(6)) - clusters.begin());
  const Vec3 position = coarse->position(VertexId(merged));
  EXPECT_NEAR(position.x, 0.5, 1e-6);
  EXPECT_NEAR(position.y, 0.5, 1e-6);
  EXPECT_NEAR(position.z, 0.0, 1e-6);
}

TEST(CoarseningTest, OpenGridOfBlocksKeepsItsBoundary) {
  // A 6 x 6 grid in 3 x 3 blocks of 2 x 2 squares: four interior corners of four blocks
  // (two triangles each) and eight boundary vertices between two blocks (boundary edges).
  const Prepared p = Prepare(testing::Grid(6));
  std::vector<ClusterId> labels;
  for (int y = 0; y < 6; ++y) {
    for (int x = 0; x < 6; ++x) {
      const ClusterId block((y / 2) * 3 + x / 2);
      labels.push_back(block);
      labels.push_back(block);
    }
  }
  absl::StatusOr<TriangleMesh> coarse = CoarsenMesh(p.mesh, p.adjacency, labels);
  ASSERT_TRUE(coarse.ok()) << coarse.status();
  ExpectValidCoarseMesh(*coarse, 9, /*closed=*/false);
  EXPECT_EQ(coarse->num_faces(), 8u);
  const Topology topology = TopologyOf(*coarse);
  EXPECT_EQ(topology.euler, 1);  // a disc, like the grid
  EXPECT_EQ(topology.boundary_edges, 8);
  // Faces keep the grid's +z orientation.
  for (size_t f = 0; f < coarse->num_faces(); ++f) {
    const FaceId face(static_cast<uint32_t>(f));
    const Vec3 a = coarse->position(coarse->corner(face, 0));
    const Vec3 normal = Cross(coarse->position(coarse->corner(face, 1)) - a,
                              coarse->position(coarse->corner(face, 2)) - a);
    EXPECT_GT(normal.z, 0) << f;
  }
}

TEST(CoarseningTest, BoundaryVertexOfThreeClustersGivesABoundaryTriangle) {
  // A 4 x 4 grid: left half, and the right half split into bottom and top. At the bottom
  // of the middle line two clusters meet on the boundary, at (2, 2) three meet inside, on
  // the right side the split meets the boundary: one triangle, three boundary edges.
  const Prepared p = Prepare(testing::Grid(4));
  std::vector<ClusterId> labels;
  for (int y = 0; y < 4; ++y) {
    for (int x = 0; x < 4; ++x) {
      const ClusterId c(x < 2 ? 0 : (y < 2 ? 1 : 2));
      labels.push_back(c);
      labels.push_back(c);
    }
  }
  absl::StatusOr<TriangleMesh> coarse = CoarsenMesh(p.mesh, p.adjacency, labels);
  ASSERT_TRUE(coarse.ok()) << coarse.status();
  ExpectValidCoarseMesh(*coarse, 3, /*closed=*/false);
  ASSERT_EQ(coarse->num_faces(), 1u);
  EXPECT_EQ(TopologyOf(*coarse).boundary_edges, 3);
  // Counter-clockwise seen from +z: left, bottom-right, top-right (in some rotation).
  std::vector<uint32_t> triangle = coarse->indices;
  std::rotate(triangle.begin(), std::min_element(triangle.begin(), triangle.end()), triangle.end());
  EXPECT_EQ(triangle, (std::vector<uint32_t>{0, 1, 2}));
}

TEST(CoarseningTest, RejectsBadInput) {
  const Prepared p = Prepare(testing::Tetrahedron());
  EXPECT_EQ(CoarsenMesh(p.mesh, p.adjacency, AsLabels({0, 1, 2})).status().code(),
            absl::StatusCode::kInvalidArgument);
  std::vector<ClusterId> with_invalid = AsLabels({0, 1, 2, 3});
  with_invalid[2] = ClusterId::Invalid();
  absl::Status invalid = CoarsenMesh(p.mesh, p.adjacency, with_invalid).status();
  EXPECT_EQ(invalid.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(invalid.message(), HasSubstr("face 2"));
  FaceAdjacency short_adjacency = p.adjacency;
  short_adjacency.neighbours.pop_back();
  EXPECT_EQ(CoarsenMesh(p.mesh, short_adjacency, AsLabels({0, 1, 2, 3})).status().code(),
            absl::StatusCode::kInvalidArgument);
  FaceAdjacency wrong_adjacency = p.adjacency;
  wrong_adjacency.neighbours[0][0] = FaceId(17);
  EXPECT_EQ(CoarsenMesh(p.mesh, wrong_adjacency, AsLabels({0, 1, 2, 3})).status().code(),
            absl::StatusCode::kInvalidArgument);
  wrong_adjacency.neighbours[0][0] = FaceId(0);  // in range, but not across that edge
  EXPECT_EQ(CoarsenMesh(p.mesh, wrong_adjacency, AsLabels({0, 1, 2, 3})).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(CoarsenMesh(p.mesh, p.adjacency, AsLabels({0, 1, 2, 3}), {.max_repair_rounds = -1})
                .status()
                .code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(CoarsenMesh(p.mesh, p.adjacency, AsLabels({0, 1, 2, 3}),
                        {.quadric_relative_eigenvalue = std::nan("")})
                .status()
                .code(),
            absl::StatusCode::kInvalidArgument);
}

TEST(CoarseningTest, RejectsAnInconsistentlyOrientedMesh) {
  TriangleMesh mesh = testing::Tetrahedron();
  std::swap(mesh.indices[1], mesh.indices[2]);  // flip face 0
  const Prepared p = Prepare(mesh);
  absl::Status status = CoarsenMesh(p.mesh, p.adjacency, AsLabels({0, 1, 2, 3})).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(status.message(), HasSubstr("oriented inconsistently"));
}

constexpr CoarseningOptions kStrict = {.repair_clusters = false};

TEST(CoarseningTest, DisconnectedClusterIsRejectedOrRepaired) {
  // A 4 x 4 grid in 2 x 2 blocks; the far corner's square (faces 30, 31) joins block 0.
  const Prepared p = Prepare(testing::Grid(4));
  std::vector<ClusterId> labels;
  for (int y = 0; y < 4; ++y) {
    for (int x = 0; x < 4; ++x) labels.insert(labels.end(), 2, ClusterId((y / 2) * 2 + x / 2));
  }
  labels[30] = labels[31] = ClusterId(0);
  absl::Status status = CoarsenMesh(p.mesh, p.adjacency, labels, kStrict).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(status.message(),
              HasSubstr("cluster 0 is not one edge-connected piece: faces 0 and 30"));

  // Repaired: the stray square goes back to block 3 for the connectivity; the vertex of
  // cluster 0 is still placed from all its faces.
  absl::StatusOr<CoarseMesh> repaired = CoarsenMeshWithReport(p.mesh, p.adjacency, labels);
  ASSERT_TRUE(repaired.ok()) << repaired.status();
  ExpectValidCoarseMesh(repaired->mesh, 4, /*closed=*/false);
  EXPECT_EQ(repaired->repaired_clusters, 1u);
  EXPECT_EQ(repaired->moved_faces, 2u);
  EXPECT_EQ(repaired->mesh.num_faces(), 2u);  // the four blocks' corner at (2, 2)
  EXPECT_EQ(TopologyOf(repaired->mesh).euler, 1);
  const FaceMeasures measures = ComputeFaceMeasures(p.mesh);
  Vec3 centroid;
  for (int f : {0, 1, 2, 3, 8, 9, 10, 11, 30, 31}) centroid += measures.centroid[f] * 0.1;
  EXPECT_NEAR(Norm(repaired->mesh.position(VertexId(0)) - centroid), 0, 1e-6);
}

TEST(CoarseningTest, ClusterTouchingItselfAtAVertexIsRejectedOrRepaired) {
  // 5 x 5 grid; cluster 1 winds from square (1, 1) down, right and up to square (2, 2),
  // touching itself at grid vertex (2, 2) = 14 around the enclosed square (2, 1).
  const Prepared p = Prepare(testing::Grid(5));
  std::vector<ClusterId> labels(p.mesh.num_faces(), ClusterId(0));
  for (auto [x, y] :
       std::vector<std::pair<int, int>>{{1, 1}, {1, 0}, {2, 0}, {3, 0}, {3, 1}, {3, 2}, {2, 2}}) {
    labels[2 * (y * 5 + x)] = labels[2 * (y * 5 + x) + 1] = ClusterId(1);
  }
  labels[2 * (1 * 5 + 2)] = labels[2 * (1 * 5 + 2) + 1] = ClusterId(2);
  absl::Status status = CoarsenMesh(p.mesh, p.adjacency, labels, kStrict).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(status.message(),
              HasSubstr("cluster 1 is not a disc: it touches itself at vertex 14"));

  absl::StatusOr<CoarseMesh> repaired = CoarsenMeshWithReport(p.mesh, p.adjacency, labels);
  ASSERT_TRUE(repaired.ok()) << repaired.status();
  ExpectValidCoarseMesh(repaired->mesh, 3, /*closed=*/false);
  EXPECT_GE(repaired->repaired_clusters, 1u);
  EXPECT_EQ(TopologyOf(repaired->mesh).euler, 1);
}

TEST(CoarseningTest, TorusKeepsItsGenusWithEnoughClusters) {
  // A torus (V - E + F = 0) in 4 x 4 blocks of 3 x 2 squares: 16 discs, each meeting
  // 8 others, corners of four blocks: a coarse torus of 16 vertices and 32 triangles.
  const Prepared p = Prepare(MakeTorus(12, 8));
  std::vector<ClusterId> labels;
  for (int i = 0; i < 12; ++i) {
    for (int j = 0; j < 8; ++j) labels.insert(labels.end(), 2, ClusterId(i / 3 * 4 + j / 2));
  }
  absl::StatusOr<CoarseMesh> coarse = CoarsenMeshWithReport(p.mesh, p.adjacency, labels, kStrict);
  ASSERT_TRUE(coarse.ok()) << coarse.status();
  ExpectValidCoarseMesh(coarse->mesh, 16, /*closed=*/true);
  EXPECT_EQ(coarse->mesh.num_faces(), 32u);
  EXPECT_EQ(TopologyOf(coarse->mesh).euler, 0);
}

TEST(CoarseningTest, ClusterWithAHandleOrAroundATubeIsRejected) {
  const Prepared p = Prepare(MakeTorus(12, 8));
  // Three small clusters; the rest of the torus, with its handle, is cluster 9.
  std::vector<ClusterId> labels(p.mesh.num_faces(), ClusterId(9));
  labels[0] = labels[1] = ClusterId(1);
  labels[40] = labels[41] = ClusterId(2);
  labels[100] = labels[101] = ClusterId(3);
  absl::Status handle = CoarsenMesh(p.mesh, p.adjacency, labels, kStrict).status();
  EXPECT_EQ(handle.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(handle.message(), HasSubstr("cluster 9 is not a disc (Euler characteristic -3)"));
  // Four vertices cannot make a torus (that takes seven): repair cannot help either, and
  // the result is an error, not a broken mesh.
  EXPECT_EQ(CoarsenMesh(p.mesh, p.adjacency, labels).status().code(),
            absl::StatusCode::kFailedPrecondition);

  // One ring of squares around the tube (i = 0) is an annulus; the rest is in blocks.
  std::vector<ClusterId> rings;
  for (int i = 0; i < 12; ++i) {
    for (int j = 0; j < 8; ++j) {
      rings.insert(rings.end(), 2, i == 0 ? ClusterId(1000) : ClusterId((i - 1) / 3 * 2 + j / 4));
    }
  }
  absl::Status ring = CoarsenMesh(p.mesh, p.adjacency, rings, kStrict).status();
  EXPECT_EQ(ring.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(ring.message(), HasSubstr("cluster 1000 is not a disc (Euler characteristic 0)"));
}

TEST(CoarseningTest, RejectsTwoClustersWithoutACorner) {
  const SubdividedCube cube = MakeCube(2);
  const Prepared p = Prepare(cube.mesh);
  std::vector<ClusterId> labels;
  for (size_t f = 0; f < cube.side.size(); ++f) labels.push_back(ClusterId(cube.side[f] < 3));
  absl::Status status = CoarsenMesh(p.mesh, p.adjacency, labels).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(status.message(), HasSubstr("no vertex of the mesh is a corner"));
}

TEST(CoarseningTest, ThinClusterBetweenTwoOthersIsFlippedIn) {
  // Cube, 4 x 4 squares per side, one cluster per side, but the top side (+z) is split into
  // halves A = 2 (i < 2) and B = 6, and a 2 x 1 cluster C = 7 straddles their border in the
  // middle: C meets only A and B, which meet along two arcs. The two corners at C's ends
  // give (C, A, B) and (C, B, A), and A-B gets two edges; one is flipped to C.
  const SubdividedCube cube = MakeCube(4);
  const Prepared p = Prepare(cube.mesh);
  std::vector<ClusterId> labels;
  for (size_t f = 0; f < cube.side.size(); ++f) {
    uint32_t label = cube.side[f];
    if (cube.side[f] == 2) {
      const auto [i, j] = cube.square[f];
      label = i < 2 ? 2 : 6;
      if (j == 1 && (i == 1 || i == 2)) label = 7;
    }
    labels.push_back(ClusterId(label));
  }
  absl::StatusOr<CoarseMesh> coarse = CoarsenMeshWithReport(p.mesh, p.adjacency, labels, kStrict);
  ASSERT_TRUE(coarse.ok()) << coarse.status();
  ExpectValidCoarseMesh(coarse->mesh, 8, /*closed=*/true);
  EXPECT_EQ(TopologyOf(coarse->mesh).euler, 2);
  EXPECT_EQ(coarse->edge_flips, 1u);
  EXPECT_EQ(coarse->mesh.num_faces(), 12u);  // 2V - 4
  EXPECT_GT(SignedVolume(coarse->mesh), 0);
  const auto clusters = coarse->vertex_cluster;
  const uint32_t thin = static_cast<uint32_t>(
      std::find(clusters.begin(), clusters.end(), ClusterId(7)) - clusters.begin());
  EXPECT_EQ(std::count(coarse->mesh.indices.begin(), coarse->mesh.indices.end(), thin), 3);
}

// Labels for the faces of testing::Grid(n, holes) from a label per kept square.
template <typename LabelOf>
std::vector<ClusterId> GridLabels(int n, const std::vector<int>& holes, LabelOf label_of) {
  std::vector<ClusterId> labels;
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      if (std::find(holes.begin(), holes.end(), y * n + x) != holes.end()) continue;
      labels.insert(labels.end(), 2, ClusterId(label_of(x, y)));
    }
  }
  return labels;
}

std::vector<int> Squares(int n, int x0, int x1, int y0, int y1) {
  std::vector<int> squares;
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) squares.push_back(y * n + x);
  }
  return squares;
}

TEST(CoarseningTest, HoleInsideOneClusterIsClosedOver) {
  // A 15 x 15 grid in 5 x 5 blocks; the middle block has two one-square holes inside it.
  const std::vector<int> holes = {7 * 15 + 6, 7 * 15 + 8};
  const Prepared p = Prepare(testing::Grid(15, holes));
  const std::vector<ClusterId> labels =
      GridLabels(15, holes, [](int x, int y) { return (y / 5) * 3 + x / 5; });
  absl::StatusOr<CoarseMesh> coarse = CoarsenMeshWithReport(p.mesh, p.adjacency, labels);
  ASSERT_TRUE(coarse.ok()) << coarse.status();
  ExpectValidCoarseMesh(coarse->mesh, 9, /*closed=*/false);
  EXPECT_EQ(coarse->closed_boundary_loops, 2u);
  EXPECT_EQ(coarse->repaired_clusters, 0u);  // a disc once its holes are filled
  EXPECT_EQ(TopologyOf(coarse->mesh).euler, 1);
  EXPECT_EQ(TopologyOf(coarse->mesh).boundary_edges, 8);
}

TEST(CoarseningTest, HoleMeetingThreeClustersStaysOpen) {
  // A 12 x 12 grid with a 2 x 2 hole in the middle, three sectors around it (within two
  // squares) and the four quadrants outside: an annulus, V - E + F = 0, which the coarse
  // mesh keeps with a boundary loop of three edges around the hole.
  const std::vector<int> hole = Squares(12, 5, 6, 5, 6);
  const Prepared p = Prepare(testing::Grid(12, hole));
  const std::vector<ClusterId> labels = GridLabels(12, hole, [](int x, int y) {
    if (x >= 3 && x <= 8 && y >= 3 && y <= 8) {
      const double angle = std::atan2(y + 0.5 - 6, x + 0.5 - 6);
      return 4 + static_cast<int>((angle + std::numbers::pi) / (2 * std::numbers::pi / 3)) % 3;
    }
    return (y >= 6) * 2 + (x >= 6);
  });
  absl::StatusOr<CoarseMesh> coarse = CoarsenMeshWithReport(p.mesh, p.adjacency, labels);
  ASSERT_TRUE(coarse.ok()) << coarse.status();
  ExpectValidCoarseMesh(coarse->mesh, 7, /*closed=*/false);
  EXPECT_EQ(coarse->closed_boundary_loops, 0u);
  EXPECT_EQ(TopologyOf(coarse->mesh).euler, 0);
  EXPECT_EQ(TopologyOf(coarse->mesh).boundary_edges, 4 + 3);
}

TEST(CoarseningTest, ClusterBetweenTwoHolesClosesOneOfThem) {
  // A 12 x 12 grid with 2 x 2 holes H1 at squares (2..3, 4..5) and H2 at (8..9, 4..5).
  // Cluster X (x in 4..7, y in 3..8) lies between them; each hole also meets a top and a
  // bottom cluster on its far side, away from the outer boundary. X on two coarse boundary
  // loops would be non-manifold,
  // so one hole is closed over and the other keeps its loop.
  std::vector<int> holes = Squares(12, 2, 3, 4, 5);
  for (int square : Squares(12, 8, 9, 4, 5)) holes.push_back(square);
  const Prepared p = Prepare(testing::Grid(12, holes));
  const Topology input = TopologyOf(p.mesh);
  ASSERT_EQ(input.euler, -1);
  const std::vector<ClusterId> labels = GridLabels(12, holes, [](int x, int y) {
    if (y >= 9) return 0;                         // top
    if (y <= 2) return 1;                         // bottom
    if (x == 0 || x == 11) return 7 + (x == 11);  // left and right, on the outer boundary
    if (x >= 4 && x <= 7) return 2;               // X
    return (x > 7 ? 5 : 3) + (y >= 5 ? 1 : 0);    // beside H1, beside H2
  });
  absl::StatusOr<CoarseMesh> coarse = CoarsenMeshWithReport(p.mesh, p.adjacency, labels);
  ASSERT_TRUE(coarse.ok()) << coarse.status();
  ExpectValidCoarseMesh(coarse->mesh, 9, /*closed=*/false);
  EXPECT_EQ(coarse->closed_boundary_loops, 1u);
  EXPECT_EQ(TopologyOf(coarse->mesh).euler, input.euler + 1);
}

std::string MeshPath(const std::string& name) {
  for (const std::string& path : {testing::DataPath(name), testing::DataPath("bench/" + name),
                                  "/tmp/cgaldata/data/meshes/" + name}) {
    if (std::filesystem::exists(path)) return path;
  }
  return "";
}

// Real meshes clustered by HC (CVD) and by graph Voronoi growth at many k: the coarse mesh
// is a valid manifold with k vertices and the input's Euler characteristic, closed and
// outward like the input.
struct RealMeshCase {
  std::string name;
  bool grown;  // also clusterings grown from random seeds

  friend void PrintTo(const RealMeshCase& c, std::ostream* os) { *os << c.name; }
};

class RealMeshCoarseningTest : public ::testing::TestWithParam<RealMeshCase> {};

TEST_P(RealMeshCoarseningTest, ClosedMeshGivesClosedManifoldWithKVertices) {
  const std::string path = MeshPath(GetParam().name);
  ASSERT_FALSE(path.empty()) << GetParam().name
                             << " not found: bash scripts/fetch-bench-meshes.sh --no-1m puts it in "
                                "data/bench/ (scripts/test.sh does)";
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(path);
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  const Prepared p = Prepare(*std::move(mesh));
  const Topology input = TopologyOf(p.mesh);
  ASSERT_EQ(input.boundary_edges, 0);
  const double volume = SignedVolume(p.mesh);
  for (uint32_t k : {50u, 100u, 300u, 1000u, 3000u}) {
    if (k * 4 > p.mesh.num_faces()) continue;
    for (int source = 0; source < (GetParam().grown ? 2 : 1); ++source) {
      const std::vector<ClusterId> labels =
          source == 0 ? HcClusters(p, k) : GrowClusters(p.adjacency, k, k);
      ASSERT_EQ(CountDistinct(labels), k);
      for (auto placement :
           {CoarseningOptions::Placement::kCentroid, CoarseningOptions::Placement::kQuadric}) {
        SCOPED_TRACE(absl::StrCat(
            GetParam().name, " k=", k, source == 0 ? " HC" : " grown",
            placement == CoarseningOptions::Placement::kQuadric ? " quadric" : " centroid"));
        absl::StatusOr<CoarseMesh> coarse =
            CoarsenMeshWithReport(p.mesh, p.adjacency, labels, {.placement = placement});
        ASSERT_TRUE(coarse.ok()) << coarse.status();
        ExpectValidCoarseMesh(coarse->mesh, k, /*closed=*/true);
        EXPECT_EQ(TopologyOf(coarse->mesh).euler, input.euler);
        EXPECT_GT(SignedVolume(coarse->mesh) * volume, 0);
        EXPECT_EQ(coarse->vertex_cluster, CoarseVertexClusters(labels));
      }
    }
  }
}

// elephant.off has genus 3 through thin handles (about ten edges around); clusterings
// grown from random seeds at k = 50 can leave fewer than three clusters around one, which
// has no valid coarse mesh, so only HC's are checked there.
INSTANTIATE_TEST_SUITE_P(Meshes, RealMeshCoarseningTest,
                         ::testing::Values(RealMeshCase{"fandisk.off", true},
                                           RealMeshCase{"elephant.off", false},
                                           RealMeshCase{"bunny00.off", true}),
                         [](const auto& info) {
                           return info.param.name.substr(0, info.param.name.find('.'));
                         });

TEST(CoarseningTest, ElephantWithHolesKeepsABoundary) {
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(testing::DataPath("elephant-with-holes.off"));
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  const Prepared p = Prepare(*std::move(mesh));
  const Topology input = TopologyOf(p.mesh);
  ASSERT_GT(input.boundary_edges, 0);
  for (uint32_t k : {100u, 250u, 600u, 1000u}) {
    const std::vector<ClusterId> labels = HcClusters(p, k);
    absl::StatusOr<CoarseMesh> coarse = CoarsenMeshWithReport(p.mesh, p.adjacency, labels);
    ASSERT_TRUE(coarse.ok()) << k << ": " << coarse.status();
    ExpectValidCoarseMesh(coarse->mesh, k, /*closed=*/false);
    const Topology topology = TopologyOf(coarse->mesh);
    EXPECT_GT(topology.boundary_edges, 0) << k;
    // Each of the 106 holes that is closed over adds one to the characteristic.
    EXPECT_LT(coarse->closed_boundary_loops, 106u) << k;
    EXPECT_EQ(topology.euler, input.euler + coarse->closed_boundary_loops) << k;
  }
}

TEST(CoarseningTest, OpenGridClusteredByGrowthKeepsItsBoundary) {
  const Prepared p = Prepare(testing::Grid(30));
  for (uint32_t k : {10u, 40u, 150u}) {
    const std::vector<ClusterId> labels = GrowClusters(p.adjacency, k, k);
    absl::StatusOr<TriangleMesh> coarse = CoarsenMesh(p.mesh, p.adjacency, labels);
    ASSERT_TRUE(coarse.ok()) << k << ": " << coarse.status();
    ExpectValidCoarseMesh(*coarse, k, /*closed=*/false);
    const Topology topology = TopologyOf(*coarse);
    EXPECT_EQ(topology.euler, 1) << k;
    EXPECT_GT(topology.boundary_edges, 0) << k;
  }
}

}  // namespace
}  // namespace mlclust

namespace mlclust {
namespace {

// An MWCVD clustering of fandisk (ML with the w^M weight, stopped at k clusters) and the
// densities its energy uses.
struct MwcvdClustering {
  Prepared p;
  FaceMeasures measures;
  MeshEnergyOptions energy;
  std::vector<double> density;
  std::vector<ClusterId> labels;
};

const MwcvdClustering& FandiskMwcvd() {
  static const MwcvdClustering* clustering = [] {
    auto* c = new MwcvdClustering;
    c->p = Prepare(*ReadMeshFile(testing::DataPath("fandisk.off")));
    c->measures = ComputeFaceMeasures(c->p.mesh);
    c->energy.kind = MeshEnergyKind::kMwcvdMax;
    c->density = EnergyFaceDensity(c->energy, c->p.mesh, c->measures);
    HierarchyLog log;
    MultilevelOptions options;
    options.min_clusters = 300;
    auto summary =
        RunMultilevel({&c->p.mesh, &c->p.adjacency, &c->measures, c->energy}, options, log);
    EXPECT_TRUE(summary.ok()) << summary.status();
    c->labels = *log.LabelsAt(log.num_levels() - 1);
    return c;
  }();
  return *clustering;
}

// l. 783, 937: the coarse vertices of an adaptive clustering are the density-weighted
// centroids it already has (eq. 3.22), not the area-weighted ones.
TEST(CoarseVertexPlacementTest, MwcvdVerticesAreTheDensityWeightedCentroids) {
  const MwcvdClustering& c = FandiskMwcvd();
  ASSERT_EQ(CountDistinct(c.labels), 300u);
  CoarseningOptions options;
  options.face_density = c.density;
  absl::StatusOr<CoarseMesh> coarse =
      CoarsenMeshWithReport(c.p.mesh, c.p.adjacency, c.labels, options);
  ASSERT_TRUE(coarse.ok()) << coarse.status();
  ASSERT_EQ(coarse->mesh.num_vertices(), 300u);
  // Eq. 3.22 here, face by face, and the proxy of the MWCVD energy itself.
  const MwcvdEnergy energy(c.measures, c.density, MwcvdEnergy::Weight::kMax);
  std::map<ClusterId, MwcvdEnergy::Sums> sums;
  std::map<ClusterId, std::pair<Vec3, double>> weighted, plain;  // sum m g, sum m
  for (size_t f = 0; f < c.labels.size(); ++f) {
    sums[c.labels[f]] += energy.face_sums(f);
    const double mass = c.density[f] * c.measures.area[f];
    weighted[c.labels[f]].first += c.measures.centroid[f] * mass;
    weighted[c.labels[f]].second += mass;
    plain[c.labels[f]].first += c.measures.centroid[f] * c.measures.area[f];
    plain[c.labels[f]].second += c.measures.area[f];
  }
  int moved = 0;
  for (size_t v = 0; v < coarse->vertex_cluster.size(); ++v) {
    const ClusterId cluster = coarse->vertex_cluster[v];
    const Vec3 position = coarse->mesh.position(VertexId(static_cast<uint32_t>(v)));
    const Vec3 expected = weighted[cluster].first / weighted[cluster].second;
    const Vec3 proxy = energy.FitProxy(sums[cluster]).centroid + energy.origin();
    EXPECT_LT(Norm(position - expected), 1e-5) << v;
    EXPECT_LT(Norm(proxy - expected), 1e-9) << v;
    if (Norm(expected - plain[cluster].first / plain[cluster].second) > 1e-3) ++moved;
  }
  // The density matters: many vertices are away from the area-weighted centroid.
  EXPECT_GT(moved, 30);
}

TEST(CoarseVertexPlacementTest, ClosestVertexIsTheClustersMeshVertexNearestItsCentroid) {
  const MwcvdClustering& c = FandiskMwcvd();
  CoarseningOptions options;
  options.face_density = c.density;
  options.placement = CoarseningOptions::Placement::kClosestVertex;
  absl::StatusOr<CoarseMesh> coarse =
      CoarsenMeshWithReport(c.p.mesh, c.p.adjacency, c.labels, options);
  ASSERT_TRUE(coarse.ok()) << coarse.status();
  std::map<ClusterId, std::pair<Vec3, double>> weighted;
  std::map<ClusterId, std::set<uint32_t>> vertices;
  for (size_t f = 0; f < c.labels.size(); ++f) {
    const double mass = c.density[f] * c.measures.area[f];
    weighted[c.labels[f]].first += c.measures.centroid[f] * mass;
    weighted[c.labels[f]].second += mass;
    for (int i = 0; i < 3; ++i) vertices[c.labels[f]].insert(c.p.mesh.indices[3 * f + i]);
  }
  for (size_t v = 0; v < coarse->vertex_cluster.size(); ++v) {
    const ClusterId cluster = coarse->vertex_cluster[v];
    const Vec3 position = coarse->mesh.position(VertexId(static_cast<uint32_t>(v)));
    const Vec3 centroid = weighted[cluster].first / weighted[cluster].second;
    double nearest = std::numeric_limits<double>::infinity();
    bool on_a_vertex = false;
    for (uint32_t u : vertices[cluster]) {
      const Vec3 p = c.p.mesh.position(VertexId(u));
      nearest = std::min(nearest, Norm(p - centroid));
      on_a_vertex |= Norm(p - position) == 0;
    }
    EXPECT_TRUE(on_a_vertex) << v;
    EXPECT_NEAR(Norm(position - centroid), nearest, 1e-12) << v;
  }
}

TEST(CoarseVertexPlacementTest, RejectsADensityOfTheWrongSizeOrSign) {
  const Prepared p = Prepare(testing::Tetrahedron());
  const std::vector<ClusterId> labels = AsLabels({0, 1, 2, 3});
  const std::vector<double> short_density = {1, 1};
  const std::vector<double> negative = {1, 1, -1, 1};
  CoarseningOptions options;
  options.face_density = short_density;
  EXPECT_THAT(std::string(CoarsenMesh(p.mesh, p.adjacency, labels, options).status().message()),
              HasSubstr("face_density holds 2"));
  options.face_density = negative;
  EXPECT_THAT(std::string(CoarsenMesh(p.mesh, p.adjacency, labels, options).status().message()),
              HasSubstr("face 2"));
}

TEST(CoarseningTest, ACancelFlagReturnsCancelled) {
  const SubdividedCube cube = MakeCube(2);
  const Prepared p = Prepare(cube.mesh);
  std::vector<ClusterId> labels;
  for (int side : cube.side) labels.push_back(ClusterId(side));
  std::atomic<bool> cancel{true};
  CoarseningOptions options;
  options.cancel = &cancel;
  EXPECT_EQ(CoarsenMesh(p.mesh, p.adjacency, labels, options).status().code(),
            absl::StatusCode::kCancelled);
  cancel = false;
  EXPECT_TRUE(CoarsenMesh(p.mesh, p.adjacency, labels, options).ok());
}

}  // namespace
}  // namespace mlclust
