// Per-polygon clustering inside the algorithms (issue 13, MeshProblem::polygons): on a
// wavy quad grid and on CGAL's double torus of quads to heptagons, no polygon is ever
// split (every level of ML, HC, PML; EMLO's and BB's seeds and results), every cluster
// stays edge-connected, the levels' energies are those of their labels, polygons of one
// triangle give exactly the triangle run, and bad polygon lists are refused by index.
#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "core/cluster/mesh_clustering.h"
#include "core/cluster/multilevel.h"
#include "core/hierarchy/hierarchy.h"
#include "core/io/mesh_io.h"
#include "core/mesh/polygons.h"
#include "core/mesh/prepared_mesh.h"
#include "gtest/gtest.h"
#include "tests/fixtures/quad_grid.h"

namespace mlclust {
namespace {

struct PolygonMesh {
  PreparedMesh prepared;
  std::vector<uint32_t> counts;  // triangles per polygon
};

PolygonMesh Prepare(TriangleMesh mesh, std::vector<uint32_t> counts) {
  absl::StatusOr<PreparedMesh> prepared = PrepareMesh(std::move(mesh));
  EXPECT_TRUE(prepared.ok()) << prepared.status();
  return {*std::move(prepared), std::move(counts)};
}

// testing::WavyQuadGrid with its quads as the polygons.
PolygonMesh WavyQuadGrid(int n) {
  return Prepare(::mlclust::testing::WavyQuadGrid(n), std::vector<uint32_t>(n * n, 2));
}

// CGAL's double-torus-example.off (202 quads, 12 pentagons, 4 hexagons, 2 heptagons, a
// closed surface of genus 2), read by our reader; the counts from its face lines.
PolygonMesh DoubleTorus() {
  const std::string path =
      std::string(MLCLUST_DATA_DIR) + "/../tests/fixtures/cgal_double_torus_example.off";
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(path);
  EXPECT_TRUE(mesh.ok()) << mesh.status();
  std::ifstream file(path);
  std::vector<std::string> lines;
  for (std::string line; std::getline(file, line);) {
    if (line.empty() || line[0] == '#') continue;
    lines.push_back(line);
  }
  std::istringstream header(lines[1]);
  size_t vertices = 0, faces = 0;
  header >> vertices >> faces;
  std::vector<uint32_t> counts;
  for (size_t f = 0; f < faces; ++f) {
    std::istringstream face(lines[2 + vertices + f]);
    uint32_t corners = 0;
    face >> corners;
    counts.push_back(corners - 2);
  }
  return Prepare(*std::move(mesh), std::move(counts));
}

uint32_t CountClusters(std::span<const ClusterId> labels) {
  std::vector<uint32_t> compact;
  return CompactClusterIds(labels, compact);
}

// No polygon split, every cluster one edge-connected piece; returns the cluster count.
uint32_t ExpectWholeAndConnected(const PolygonMesh& m, const MeshPolygons& polygons,
                                 std::span<const ClusterId> labels, const std::string& what) {
  EXPECT_TRUE(PolygonLabelsOfFaces(polygons, labels).ok())
      << what << ": " << PolygonLabelsOfFaces(polygons, labels).status();
  std::vector<uint32_t> compact, component;
  const uint32_t clusters = CompactClusterIds(labels, compact);
  EXPECT_EQ(LabelFaceComponents(m.prepared.adjacency, component, compact), clusters)
      << what << ": a cluster is in several pieces";
  return clusters;
}

// The post-pass the CLI had (client/polygons.h): each polygon to the cluster holding most
// of its area, ties to the smaller id.
std::vector<ClusterId> MajorityPerPolygon(const PolygonMesh& m, const MeshPolygons& polygons,
                                          std::span<const ClusterId> labels) {
  std::vector<ClusterId> out(labels.begin(), labels.end());
  for (uint32_t p = 0; p < polygons.num_polygons(); ++p) {
    std::vector<std::pair<uint32_t, double>> area;
    for (uint32_t f = polygons.first_face[p]; f < polygons.first_face[p + 1]; ++f) {
      auto it = std::find_if(area.begin(), area.end(),
                             [&](const auto& e) { return e.first == labels[f].value(); });
      if (it == area.end()) {
        area.push_back({labels[f].value(), 0.0});
        it = area.end() - 1;
      }
      it->second += m.prepared.measures.area[f];
    }
    std::pair<uint32_t, double> best = area[0];
    for (const auto& e : area) {
      if (e.second > best.second || (e.second == best.second && e.first < best.first)) best = e;
    }
    for (uint32_t f = polygons.first_face[p]; f < polygons.first_face[p + 1]; ++f) {
      out[f] = ClusterId(best.first);
    }
  }
  return out;
}

// fandisk (data/fandisk.off, 12,946 triangles), every triangle a polygon of its own.
PolygonMesh FandiskTriangles() {
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(std::string(MLCLUST_DATA_DIR) + "/fandisk.off");
  EXPECT_TRUE(mesh.ok()) << mesh.status();
  const size_t faces = mesh->num_faces();
  return Prepare(*std::move(mesh), std::vector<uint32_t>(faces, 1));
}

class PolygonClusteringTest : public ::testing::TestWithParam<int> {
 protected:
  PolygonMesh Mesh() const {
    return GetParam() == 0   ? WavyQuadGrid(12)
           : GetParam() == 1 ? DoubleTorus()
                             : FandiskTriangles();
  }
};

TEST_P(PolygonClusteringTest, HierarchiesNeverSplitAPolygon) {
  const PolygonMesh m = Mesh();
  absl::StatusOr<MeshPolygons> polygons = MakeMeshPolygons(m.counts, m.prepared.adjacency);
  ASSERT_TRUE(polygons.ok()) << polygons.status();
  for (MeshEnergyKind energy : {MeshEnergyKind::kCvd, MeshEnergyKind::kPlanar}) {
    for (int algorithm = 0; algorithm < 4; ++algorithm) {  // ML, HC, PML, ML with BB
      const std::string what =
          std::string(MeshEnergyName(energy)) + " algorithm " + std::to_string(algorithm);
      MeshProblem problem = MakeMeshProblem(m.prepared, {.kind = energy});
      problem.polygons = &*polygons;
      MultilevelOptions options;
      if (algorithm == 1) options.optimizer = MultilevelOptions::Optimizer::kNone;
      if (algorithm == 2) options.parallel = true;
      if (algorithm == 3) options.optimizer = MultilevelOptions::Optimizer::kBoundaryBased;
      HierarchyLog log;
      absl::StatusOr<MultilevelSummary> summary = RunMultilevel(problem, options, log);
      ASSERT_TRUE(summary.ok()) << what << ": " << summary.status();
      ASSERT_EQ(log.num_elements(), m.prepared.mesh.num_faces());
      // Level 0: one cluster per polygon, with the polygons' energy.
      EXPECT_EQ(log.cluster_count(0), polygons->num_polygons()) << what;
      for (size_t level = 0; level < log.num_levels(); ++level) {
        absl::StatusOr<std::vector<ClusterId>> labels = log.LabelsAt(level);
        ASSERT_TRUE(labels.ok()) << labels.status();
        const std::string at = what + " level " + std::to_string(level);
        EXPECT_EQ(ExpectWholeAndConnected(m, *polygons, *labels, at), log.cluster_count(level))
            << at;
        const double energy_of_labels =
            MeshEnergyOfLabels(problem.energy, m.prepared.mesh, *labels);
        EXPECT_NEAR(log.energy(level), energy_of_labels, 1e-9 * (1 + energy_of_labels)) << at;
        // Cluster ids are face ids: the first face of the polygon the cluster started from.
        for (ClusterId c : *labels) {
          EXPECT_EQ(polygons->first_face[polygons->polygon_of_face[c.value()]], c.value());
        }
      }
      EXPECT_EQ(log.cluster_count(log.num_levels() - 1), 1u) << what;
    }
  }
}

TEST_P(PolygonClusteringTest, EmloAndBbMoveWholePolygons) {
  const PolygonMesh m = Mesh();
  absl::StatusOr<MeshPolygons> polygons = MakeMeshPolygons(m.counts, m.prepared.adjacency);
  ASSERT_TRUE(polygons.ok()) << polygons.status();
  for (MeshEnergyKind energy : {MeshEnergyKind::kCvd, MeshEnergyKind::kPlanar}) {
    for (uint32_t k : {2u, 10u, 30u}) {
      for (auto method : {SeedOptions::Method::kLNeighbourhood, SeedOptions::Method::kRandom}) {
        const std::string what = std::string(MeshEnergyName(energy)) + " k " + std::to_string(k) +
                                 (method == SeedOptions::Method::kRandom ? " random" : " l");
        MeshProblem problem = MakeMeshProblem(m.prepared, {.kind = energy});
        problem.polygons = &*polygons;
        SeedOptions seeds;
        seeds.clusters = k;
        seeds.method = method;
        absl::StatusOr<std::vector<ClusterId>> initial = InitialClusters(problem, seeds);
        ASSERT_TRUE(initial.ok()) << what << ": " << initial.status();
        EXPECT_EQ(ExpectWholeAndConnected(m, *polygons, *initial, what + " seeds"), k);

        std::vector<ClusterId> emlo = *initial;
        absl::StatusOr<OptimizeResult> result = OptimizeEmlo(problem, emlo);
        ASSERT_TRUE(result.ok()) << what << ": " << result.status();
        EXPECT_EQ(ExpectWholeAndConnected(m, *polygons, emlo, what + " EMLO"), k);
        EXPECT_LE(result->energy, result->initial_energy);
        EXPECT_NEAR(result->energy, MeshEnergyOfLabels(problem.energy, m.prepared.mesh, emlo),
                    1e-9 * (1 + result->energy));

        std::vector<ClusterId> bb = *initial;
        result = OptimizeBoundaryBased(problem, bb);
        ASSERT_TRUE(result.ok()) << what << ": " << result.status();
        EXPECT_EQ(ExpectWholeAndConnected(m, *polygons, bb, what + " BB"), k);
        EXPECT_LE(result->energy, result->initial_energy * (1 + 1e-12));
      }
    }
  }
}

// Seeds of `clusters`, and EMLO and BB from them, give the same labels on `triangles` and
// on `singles` (the same mesh with polygons of one triangle each).
void ExpectSameSeedsEmloAndBb(const MeshProblem& triangles, const MeshProblem& singles,
                              uint32_t clusters) {
  SeedOptions seeds;
  seeds.clusters = clusters;
  absl::StatusOr<std::vector<ClusterId>> a = InitialClusters(triangles, seeds);
  absl::StatusOr<std::vector<ClusterId>> b = InitialClusters(singles, seeds);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(*a, *b);
  std::vector<ClusterId> emlo_a = *a, emlo_b = *b, bb_a = *a, bb_b = *b;
  ASSERT_TRUE(OptimizeEmlo(triangles, emlo_a).ok());
  ASSERT_TRUE(OptimizeEmlo(singles, emlo_b).ok());
  EXPECT_EQ(emlo_a, emlo_b);
  ASSERT_TRUE(OptimizeBoundaryBased(triangles, bb_a).ok());
  ASSERT_TRUE(OptimizeBoundaryBased(singles, bb_b).ok());
  EXPECT_EQ(bb_a, bb_b);
}

// Polygons of one triangle each are the triangles: the same levels, seeds and results as
// without polygons (the polygon path's sums, dual graph and ring test are the faces').
TEST_P(PolygonClusteringTest, OneTrianglePolygonsAreTheTriangleRun) {
  const PolygonMesh m = Mesh();
  const std::vector<uint32_t> ones(m.prepared.mesh.num_faces(), 1);
  absl::StatusOr<MeshPolygons> polygons = MakeMeshPolygons(ones, m.prepared.adjacency);
  ASSERT_TRUE(polygons.ok()) << polygons.status();
  const MeshProblem triangles = MakeMeshProblem(m.prepared);
  MeshProblem singles = triangles;
  singles.polygons = &*polygons;
  HierarchyLog expected, got;
  ASSERT_TRUE(RunMultilevel(triangles, {}, expected).ok());
  ASSERT_TRUE(RunMultilevel(singles, {}, got).ok());
  ASSERT_EQ(got.num_levels(), expected.num_levels());
  for (size_t level = 0; level < got.num_levels(); ++level) {
    EXPECT_EQ(*got.LabelsAt(level), *expected.LabelsAt(level)) << "level " << level;
    EXPECT_NEAR(got.energy(level), expected.energy(level), 1e-9) << "level " << level;
  }
  ExpectSameSeedsEmloAndBb(triangles, singles, 12);
}

// For the CVD and planar energies: ML on `m`'s triangles and on its `polygons`, handed to
// check(energy, triangles problem, polygons problem, triangles' levels, polygons' levels).
template <typename Check>
void MlWithAndWithoutPolygons(const PolygonMesh& m, const MeshPolygons& polygons, Check&& check) {
  for (MeshEnergyKind energy : {MeshEnergyKind::kCvd, MeshEnergyKind::kPlanar}) {
    SCOPED_TRACE(MeshEnergyName(energy));
    const MeshProblem triangles = MakeMeshProblem(m.prepared, {.kind = energy});
    MeshProblem whole = triangles;
    whole.polygons = &polygons;
    HierarchyLog on_triangles, on_polygons;
    ASSERT_TRUE(RunMultilevel(triangles, {}, on_triangles).ok());
    ASSERT_TRUE(RunMultilevel(whole, {}, on_polygons).ok());
    check(energy, triangles, whole, on_triangles, on_polygons);
  }
}

// ML on the polygons against the post-pass on the triangles' ML at the same K: printed for
// BENCHMARKS.md ("Per-polygon clustering inside the algorithms").
TEST_P(PolygonClusteringTest, EnergyAgainstThePostPass) {
  const PolygonMesh m = Mesh();
  absl::StatusOr<MeshPolygons> polygons = MakeMeshPolygons(m.counts, m.prepared.adjacency);
  ASSERT_TRUE(polygons.ok()) << polygons.status();
  MlWithAndWithoutPolygons(
      m, *polygons,
      [&](MeshEnergyKind energy, const MeshProblem& triangles, const MeshProblem& whole,
          const HierarchyLog& on_triangles, const HierarchyLog& on_polygons) {
        (void)whole;
        for (uint32_t k : {5u, 10u, 20u, 40u}) {
          const std::vector<ClusterId> post = MajorityPerPolygon(
              m, *polygons, *on_triangles.LabelsAt(*on_triangles.FirstLevelWithAtMost(k)));
          const double post_energy = MeshEnergyOfLabels(triangles.energy, m.prepared.mesh, post);
          const size_t level = *on_polygons.FirstLevelWithAtMost(k);
          std::vector<uint32_t> compact, component;
          const uint32_t post_clusters = CompactClusterIds(post, compact);
          const uint32_t post_pieces =
              LabelFaceComponents(m.prepared.adjacency, component, compact);
          std::printf(
              "%s %s k=%u: in the algorithms %.6g (%u clusters); post-pass %.6g (%u "
              "clusters, %u pieces)\n",
              GetParam() == 0 ? "quad-grid" : "double-torus", MeshEnergyName(energy), k,
              on_polygons.energy(level), on_polygons.cluster_count(level), post_energy,
              post_clusters, post_pieces);
        }
      });
}

INSTANTIATE_TEST_SUITE_P(Meshes, PolygonClusteringTest, ::testing::Values(0, 1),
                         [](const auto& info) {
                           return info.param == 0 ? std::string("QuadGrid")
                                                  : std::string("DoubleTorus");
                         });

// The exact equality of polygons of one triangle and triangles on a real mesh too.
class OneTrianglePolygonsTest : public PolygonClusteringTest {};
TEST_P(OneTrianglePolygonsTest, OnFandisk) {
  const PolygonMesh m = Mesh();
  absl::StatusOr<MeshPolygons> polygons = MakeMeshPolygons(m.counts, m.prepared.adjacency);
  ASSERT_TRUE(polygons.ok()) << polygons.status();
  MlWithAndWithoutPolygons(
      m, *polygons,
      [&](MeshEnergyKind energy, const MeshProblem& triangles, const MeshProblem& singles,
          const HierarchyLog& expected, const HierarchyLog& got) {
        (void)energy;
        ASSERT_EQ(got.num_levels(), expected.num_levels());
        ASSERT_EQ(got.num_moves(), expected.num_moves());
        for (size_t level :
             {size_t{1}, got.num_levels() / 2, got.num_levels() - 1000, got.num_levels() - 1}) {
          EXPECT_EQ(*got.LabelsAt(level), *expected.LabelsAt(level)) << "level " << level;
        }
        ExpectSameSeedsEmloAndBb(triangles, singles, 200);
      });
}
INSTANTIATE_TEST_SUITE_P(Fandisk, OneTrianglePolygonsTest, ::testing::Values(2));

TEST(MakeMeshPolygonsTest, RefusesBadListsNamingTheIndex) {
  const PolygonMesh m = WavyQuadGrid(3);  // 18 faces
  auto message = [&](std::vector<uint32_t> counts) {
    absl::StatusOr<MeshPolygons> polygons = MakeMeshPolygons(counts, m.prepared.adjacency);
    EXPECT_FALSE(polygons.ok());
    EXPECT_EQ(polygons.status().code(), absl::StatusCode::kInvalidArgument);
    return std::string(polygons.status().message());
  };
  EXPECT_NE(message({}).find("empty"), std::string::npos);
  EXPECT_NE(message({2, 2, 2, 0, 2, 2, 2, 2, 2, 2}).find("polygon 3 has 0 triangles"),
            std::string::npos);
  EXPECT_NE(message({2, 2, 2, 2}).find("add up to 8, not the mesh's 18 faces"), std::string::npos);
  EXPECT_NE(message({2, 2, 2, 2, 2, 2, 2, 2, 3}).find("up to polygon 8 add up to 19"),
            std::string::npos);
  // Faces 1 and 2: the second triangle of quad 0 and the first of quad 1, which share no
  // edge (the quads' diagonals run the same way).
  EXPECT_NE(message({1, 2, 15}).find("polygon 1 (faces 1..2) is not edge-connected"),
            std::string::npos);
  EXPECT_TRUE(MakeMeshPolygons(std::vector<uint32_t>(9, 2), m.prepared.adjacency).ok());
}

TEST(MakeMeshPolygonsTest, DriversRefuseSplitLabelsAndTheVertexCountGuard) {
  const PolygonMesh m = WavyQuadGrid(4);
  absl::StatusOr<MeshPolygons> polygons = MakeMeshPolygons(m.counts, m.prepared.adjacency);
  ASSERT_TRUE(polygons.ok());
  MeshProblem problem = MakeMeshProblem(m.prepared);
  problem.polygons = &*polygons;
  std::vector<ClusterId> split(m.prepared.mesh.num_faces(), ClusterId(0));
  split[5] = ClusterId(5);  // quad 2's second triangle alone
  absl::StatusOr<OptimizeResult> result = OptimizeEmlo(problem, split);
  ASSERT_FALSE(result.ok());
  EXPECT_NE(result.status().message().find("polygon 2's triangles are in two clusters"),
            std::string::npos)
      << result.status();
  EXPECT_FALSE(OptimizeBoundaryBased(problem, split).ok());
  std::vector<ClusterId> whole(m.prepared.mesh.num_faces(), ClusterId(0));
  for (int f = 16; f < 32; ++f) whole[f] = ClusterId(16);
  EmloOptions emlo;
  emlo.guard = ConnectivityGuardKind::kVertexBoundaryEdgeCount;
  EXPECT_EQ(OptimizeEmlo(problem, whole, emlo).status().code(), absl::StatusCode::kInvalidArgument);
  MultilevelOptions ml;
  ml.guard = ConnectivityGuardKind::kVertexBoundaryEdgeCount;
  HierarchyLog log;
  EXPECT_EQ(RunMultilevel(problem, ml, log).status().code(), absl::StatusCode::kInvalidArgument);
  SeedOptions seeds;
  seeds.clusters = 3;
  seeds.add_seeds = true;
  EXPECT_EQ(InitialClusters(problem, seeds).status().code(), absl::StatusCode::kInvalidArgument);
  seeds.add_seeds = false;
  seeds.clusters = 17;  // 16 quads
  EXPECT_EQ(InitialClusters(problem, seeds).status().code(), absl::StatusCode::kInvalidArgument);
  // Seed faces grow as their polygons; two seeds in one polygon are refused.
  const std::vector<FaceId> two = {FaceId(1), FaceId(30)};
  absl::StatusOr<std::vector<ClusterId>> grown =
      GrowClustersFromSeeds(problem, two, SeedOptions::Growth::kEnergyOrdered, nullptr);
  ASSERT_TRUE(grown.ok()) << grown.status();
  EXPECT_EQ(ExpectWholeAndConnected(m, *polygons, *grown, "grown"), 2u);
  EXPECT_EQ((*grown)[0], (*grown)[1]);
  const std::vector<FaceId> same = {FaceId(0), FaceId(1)};
  absl::StatusOr<std::vector<ClusterId>> refused =
      GrowClustersFromSeeds(problem, same, SeedOptions::Growth::kEnergyFree, nullptr);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.status().message().find("in polygon 0, which has a seed already"),
            std::string::npos)
      << refused.status();
}

}  // namespace
}  // namespace mlclust
