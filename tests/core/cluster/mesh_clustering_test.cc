#include "core/cluster/mesh_clustering.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <atomic>
#include <map>
#include <set>

#include "absl/container/flat_hash_set.h"
#include "core/io/mesh_io.h"
#include "core/mesh/connectivity_guard.h"
#include "tests/fixtures/labels.h"
#include "tests/fixtures/test_meshes.h"

namespace mlclust {
namespace {

using ::testing::HasSubstr;

using Loaded = testing::LoadedMesh;
using testing::Load;

const Loaded& File(const std::string& name) { return testing::LoadDataFile(name); }

uint32_t CountClusters(const std::vector<ClusterId>& labels) {
  absl::flat_hash_set<uint32_t> ids;
  for (ClusterId c : labels) ids.insert(c.value());
  return static_cast<uint32_t>(ids.size());
}

// Per cluster: number of edge-connected pieces and Euler characteristic V - E + F of its
// faces (1 for a disc; each hole or handle lowers it).
struct ClusterTopology {
  int pieces = 0;
  int euler = 0;
};
std::map<uint32_t, ClusterTopology> Topology(const Loaded& l,
                                             const std::vector<ClusterId>& labels) {
  std::map<uint32_t, ClusterTopology> result;
  std::map<uint32_t, std::set<uint32_t>> vertices;
  std::map<uint32_t, std::set<std::pair<uint32_t, uint32_t>>> edges;
  std::map<uint32_t, int> faces;
  for (uint32_t f = 0; f < labels.size(); ++f) {
    const uint32_t c = labels[f].value();
    ++faces[c];
    for (int i = 0; i < 3; ++i) {
      const uint32_t a = l.mesh.indices[3 * f + i], b = l.mesh.indices[3 * f + (i + 1) % 3];
      vertices[c].insert(a);
      edges[c].insert(std::minmax(a, b));
    }
  }
  const std::vector<uint32_t> pieces = testing::PiecesPerCluster(l.adjacency, labels);
  for (auto& [c, count] : faces) {
    result[c].euler =
        static_cast<int>(vertices[c].size()) - static_cast<int>(edges[c].size()) + count;
    result[c].pieces = static_cast<int>(pieces[c]);
  }
  return result;
}

TEST(InitialClustersTest, RandomAndLNeighbourhoodGiveExactlyKConnectedClusters) {
  const Loaded& l = File("fandisk.off");
  for (auto method : {SeedOptions::Method::kRandom, SeedOptions::Method::kLNeighbourhood}) {
    for (uint32_t k : {1u, 7u, 100u, 1000u}) {
      SeedOptions options;
      options.method = method;
      options.clusters = k;
      absl::StatusOr<std::vector<ClusterId>> labels = InitialClusters(l.problem(), options);
      ASSERT_TRUE(labels.ok()) << labels.status();
      EXPECT_EQ(CountClusters(*labels), k);
      for (const auto& [c, t] : Topology(l, *labels)) ASSERT_EQ(t.pieces, 1) << "cluster " << c;
    }
  }
}

TEST(InitialClustersTest, RandomSeedIsReproducible) {
  const Loaded& l = File("elephant.off");
  SeedOptions options{SeedOptions::Method::kRandom, 50, 0, 42};
  auto a = InitialClusters(l.problem(), options);
  auto b = InitialClusters(l.problem(), options);
  options.seed = 43;
  auto c = InitialClusters(l.problem(), options);
  ASSERT_TRUE(a.ok() && b.ok() && c.ok());
  EXPECT_EQ(*a, *b);
  EXPECT_NE(*a, *c);
}

TEST(InitialClustersTest, LNeighbourhoodSeedsDoNotOverlap) {
  const Loaded& l = Load(testing::Grid(20));
  // l = 0: every face a seed; larger l: fewer seeds, each pair at least 2l+1 steps apart.
  EXPECT_EQ(LNeighbourhoodSeeds(l.adjacency, 0).size(), l.mesh.num_faces());
  size_t previous = l.mesh.num_faces();
  for (uint32_t level = 1; level <= 4; ++level) {
    const std::vector<FaceId> seeds = LNeighbourhoodSeeds(l.adjacency, level);
    EXPECT_LT(seeds.size(), previous);
    previous = seeds.size();
  }
  SeedOptions options{SeedOptions::Method::kLNeighbourhood, 300, 6, 1};
  absl::Status status = InitialClusters(l.problem(), options).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(status.message()), HasSubstr("level"));
}

TEST(InitialClustersTest, BadKIsRefusedNamingTheOption) {
  const Loaded& l = File("elephant.off");
  for (uint32_t k : {0u, 100000u}) {
    absl::Status status = InitialClusters(l.problem(), {SeedOptions::Method::kRandom, k}).status();
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
    EXPECT_THAT(std::string(status.message()), HasSubstr("clusters"));
  }
  // Two components need two clusters at least.
  const Loaded split = Load(testing::Grid(4, {1, 5, 9, 13}));
  absl::Status status =
      InitialClusters(split.problem(), {SeedOptions::Method::kRandom, 1}).status();
  EXPECT_THAT(std::string(status.message()), HasSubstr("connected components"));
  EXPECT_TRUE(InitialClusters(split.problem(), {SeedOptions::Method::kRandom, 2}).ok());
}

// A 1 x 3 strip of squares, two triangles each: faces 0..5 form a chain (face i shares an
// edge with i + 1 only).
Loaded Strip() {
  return Load(
      testing::MakeMesh({0, 0, 0, 1, 0, 0, 2, 0, 0, 3, 0, 0, 0, 1, 0, 1, 1, 0, 2, 1, 0, 3, 1, 0},
                        {0, 1, 4, 4, 1, 5, 1, 2, 5, 5, 2, 6, 2, 3, 6, 6, 3, 7}));
}

using testing::RawLabels;

TEST(GrowClustersFromSeedsTest, EnergyFreeGrowthTakesTurnsInSeedOrder) {
  const Loaded l = Strip();
  auto grow = [&](std::vector<FaceId> seeds) {
    absl::StatusOr<std::vector<ClusterId>> labels = GrowClustersFromSeeds(
        l.problem(), seeds, SeedOptions::Growth::kEnergyFree, /*cancel=*/nullptr);
    EXPECT_TRUE(labels.ok()) << labels.status();
    return labels.ok() ? RawLabels(*labels) : std::vector<uint32_t>{};
  };
  // Seeds at both ends meet in the middle, one face per round each.
  EXPECT_EQ(grow({FaceId(0), FaceId(5)}), (std::vector<uint32_t>{0, 0, 0, 1, 1, 1}));
  // Seeds 0 and 2: in round one cluster 0 takes face 1 before cluster 1 can, so cluster 1
  // grows only to the right.
  EXPECT_EQ(grow({FaceId(0), FaceId(2)}), (std::vector<uint32_t>{0, 0, 1, 1, 1, 1}));
  // The same faces in the other order: now the seed at face 2 goes first and takes face 1.
  EXPECT_EQ(grow({FaceId(2), FaceId(0)}), (std::vector<uint32_t>{1, 0, 0, 0, 0, 0}));
}

TEST(GrowClustersFromSeedsTest, RefusesRepeatedSeedsAndComponentsWithoutOne) {
  const Loaded l = Strip();
  const std::vector<FaceId> repeated = {FaceId(1), FaceId(1)}, out_of_range = {FaceId(6)};
  for (auto growth : {SeedOptions::Growth::kEnergyOrdered, SeedOptions::Growth::kEnergyFree}) {
    EXPECT_EQ(GrowClustersFromSeeds(l.problem(), repeated, growth, nullptr).status().code(),
              absl::StatusCode::kInvalidArgument);
    EXPECT_EQ(GrowClustersFromSeeds(l.problem(), out_of_range, growth, nullptr).status().code(),
              absl::StatusCode::kInvalidArgument);
  }
  const Loaded split = Load(testing::Grid(4, {1, 5, 9, 13}));
  const std::vector<FaceId> one = {FaceId(0)};
  absl::Status status =
      GrowClustersFromSeeds(split.problem(), one, SeedOptions::Growth::kEnergyFree, nullptr)
          .status();
  EXPECT_THAT(std::string(status.message()), HasSubstr("component"));
}

TEST(InitialClustersTest, EveryGrowthAndReductionGivesExactlyKConnectedClusters) {
  for (const char* file : {"fandisk.off", "elephant-with-holes.off"}) {
    const Loaded& l = File(file);
    for (auto growth : {SeedOptions::Growth::kEnergyOrdered, SeedOptions::Growth::kEnergyFree}) {
      for (uint32_t k : {7u, 100u}) {
        SeedOptions options;
        options.clusters = k;
        options.level = 3;  // more seeds than k, so that the reduction runs
        ASSERT_GT(LNeighbourhoodSeeds(l.adjacency, options.level).size(), k);
        options.growth = growth;
        absl::StatusOr<std::vector<ClusterId>> merged = InitialClusters(l.problem(), options);
        options.reduction = SeedOptions::Reduction::kReseedAndRegrow;
        absl::StatusOr<std::vector<ClusterId>> reseeded = InitialClusters(l.problem(), options);
        ASSERT_TRUE(merged.ok() && reseeded.ok());
        for (const auto* labels : {&*merged, &*reseeded}) {
          EXPECT_EQ(CountClusters(*labels), k) << file;
          for (const auto& [c, t] : Topology(l, *labels)) ASSERT_EQ(t.pieces, 1) << file;
        }
        // Regrowing from the common vertices is a different partition from the merged one.
        EXPECT_NE(*merged, *reseeded) << file << " k = " << k;
      }
    }
  }
}

TEST(InitialClustersTest, TheDefaultGrowthIsTheEnergyOrderedFlood) {
  // The default must stay the flood (results of existing runs unchanged), and the
  // energy-free growth must give a different partition from the same seeds.
  const Loaded& l = File("fandisk.off");
  SeedOptions options;
  options.clusters = 50;
  absl::StatusOr<std::vector<ClusterId>> by_default = InitialClusters(l.problem(), options);
  options.growth = SeedOptions::Growth::kEnergyOrdered;
  absl::StatusOr<std::vector<ClusterId>> flood = InitialClusters(l.problem(), options);
  options.growth = SeedOptions::Growth::kEnergyFree;
  absl::StatusOr<std::vector<ClusterId>> free = InitialClusters(l.problem(), options);
  ASSERT_TRUE(by_default.ok() && flood.ok() && free.ok());
  EXPECT_EQ(*by_default, *flood);
  EXPECT_NE(*flood, *free);
}

TEST(InitialClustersTest, AddSeedsReachesKFromTooFewLNeighbourhoodSeeds) {
  const Loaded& l = File("fandisk.off");
  // l = 12 gives 37 seeds on fandisk, l = 1000 a single one (no vertex joins three
  // clusters then: the farthest-face rule adds the next seeds).
  for (uint32_t level : {12u, 1000u}) {
    SeedOptions options{SeedOptions::Method::kLNeighbourhood, 200, level, 1};
    ASSERT_LT(LNeighbourhoodSeeds(l.adjacency, level).size(), 200u);
    EXPECT_EQ(InitialClusters(l.problem(), options).status().code(),
              absl::StatusCode::kInvalidArgument);
    options.add_seeds = true;
    for (auto growth : {SeedOptions::Growth::kEnergyOrdered, SeedOptions::Growth::kEnergyFree}) {
      options.growth = growth;
      absl::StatusOr<std::vector<ClusterId>> labels = InitialClusters(l.problem(), options);
      ASSERT_TRUE(labels.ok()) << labels.status();
      EXPECT_EQ(CountClusters(*labels), 200u) << "l = " << level;
      for (const auto& [c, t] : Topology(l, *labels)) ASSERT_EQ(t.pieces, 1);
    }
  }
}

class OptimizerTest : public ::testing::TestWithParam<MeshEnergyKind> {};

TEST_P(OptimizerTest, EmloNeverRaisesTheEnergyAndKeepsClustersConnectedDiscs) {
  const Loaded& l = File("elephant-with-holes.off");
  const MeshProblem problem = l.problem(GetParam());
  absl::StatusOr<std::vector<ClusterId>> labels =
      InitialClusters(problem, {SeedOptions::Method::kRandom, 60, 0, 3});
  ASSERT_TRUE(labels.ok()) << labels.status();
  const auto before = Topology(l, *labels);
  std::vector<double> energies;
  EmloOptions options;
  options.progress_moves = 50;
  options.on_progress = [&](uint64_t, double e) { energies.push_back(e); };
  absl::StatusOr<OptimizeResult> result = OptimizeEmlo(problem, *labels, options);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_TRUE(result->converged);
  EXPECT_GT(result->moves, 0u);
  EXPECT_LT(result->energy, result->initial_energy);
  for (size_t i = 1; i < energies.size(); ++i) {
    EXPECT_LE(energies[i], energies[i - 1] * (1 + 1e-12)) << i;
  }
  EXPECT_NEAR(result->energy, MeshEnergyOfLabels(problem.energy, l.mesh, *labels),
              1e-9 * result->energy);
  EXPECT_EQ(CountClusters(*labels), 60u);
  // No cluster split, none gained a hole or a handle.
  for (const auto& [c, t] : Topology(l, *labels)) {
    EXPECT_EQ(t.pieces, 1) << "cluster " << c;
    ASSERT_TRUE(before.count(c));
    EXPECT_GE(t.euler, std::min(1, before.at(c).euler)) << "cluster " << c;
  }
}

TEST_P(OptimizerTest, BoundaryBasedNeverRaisesTheEnergyAndKeepsClustersConnected) {
  const Loaded& l = File("elephant-with-holes.off");
  const MeshProblem problem = l.problem(GetParam());
  absl::StatusOr<std::vector<ClusterId>> labels =
      InitialClusters(problem, {SeedOptions::Method::kRandom, 60, 0, 4});
  ASSERT_TRUE(labels.ok());
  std::vector<double> energies;
  BoundaryBasedOptions options;
  options.on_iteration = [&](uint32_t, double e) { energies.push_back(e); };
  absl::StatusOr<OptimizeResult> result = OptimizeBoundaryBased(problem, *labels, options);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_LE(result->energy, result->initial_energy);
  double previous = result->initial_energy;
  for (double e : energies) {
    EXPECT_LE(e, previous * (1 + 1e-12));
    previous = e;
  }
  EXPECT_EQ(CountClusters(*labels), 60u);
  for (const auto& [c, t] : Topology(l, *labels)) EXPECT_EQ(t.pieces, 1) << "cluster " << c;
}

INSTANTIATE_TEST_SUITE_P(AllMeshEnergies, OptimizerTest,
                         ::testing::Values(MeshEnergyKind::kCvd, MeshEnergyKind::kCvdAdaptive,
                                           MeshEnergyKind::kMwcvdArea,
                                           MeshEnergyKind::kMwcvdVariance,
                                           MeshEnergyKind::kMwcvdMax, MeshEnergyKind::kPlanar,
                                           MeshEnergyKind::kSphere),
                         [](const auto& info) {
                           std::string name = MeshEnergyName(info.param);
                           std::replace(name.begin(), name.end(), '-', '_');
                           return name;
                         });

TEST(OptimizerTest, GuardOffCanSplitClustersGuardOnNever) {
  // Without the guard EMLO is free to split; the guarded run on the same start must not.
  const Loaded& l = File("fandisk.off");
  const MeshProblem problem = l.problem(MeshEnergyKind::kPlanar);
  absl::StatusOr<std::vector<ClusterId>> start =
      InitialClusters(problem, {SeedOptions::Method::kRandom, 200, 0, 11});
  ASSERT_TRUE(start.ok());
  std::vector<ClusterId> guarded = *start, free = *start;
  ASSERT_TRUE(OptimizeEmlo(problem, guarded).ok());
  EmloOptions no_guard;
  no_guard.connectivity_guard = false;
  ASSERT_TRUE(OptimizeEmlo(problem, free, no_guard).ok());
  auto split = [&](const std::vector<ClusterId>& labels) {
    int count = 0;
    for (const auto& [c, t] : Topology(l, labels)) count += t.pieces > 1 || t.euler < 1;
    return count;
  };
  // The flood can leave a few clusters with holes; the guard never adds one.
  EXPECT_LE(split(guarded), split(*start));
  for (const auto& [c, t] : Topology(l, guarded)) EXPECT_EQ(t.pieces, 1);
  EXPECT_GT(split(free), split(*start));  // the guard is what keeps them whole
}

TEST(OptimizerTest, VertexBoundaryEdgeCountGuardNeverSplitsAClusterInEmloOrBb) {
  // Alg. 3.2 as the guard, kept up to date move by move in EMLO and sweep by sweep in BB.
  for (const char* file : {"fandisk.off", "elephant-with-holes.off"}) {
    const Loaded& l = File(file);
    const MeshProblem problem = l.problem(MeshEnergyKind::kPlanar);
    absl::StatusOr<std::vector<ClusterId>> start =
        InitialClusters(problem, {SeedOptions::Method::kRandom, 200, 0, 11});
    ASSERT_TRUE(start.ok());
    int start_pieces = 0;
    for (const auto& [c, t] : Topology(l, *start)) start_pieces += t.pieces;
    std::vector<ClusterId> emlo = *start, bb = *start, free = *start;
    EmloOptions emlo_options;
    emlo_options.guard = ConnectivityGuardKind::kVertexBoundaryEdgeCount;
    absl::StatusOr<OptimizeResult> emlo_result = OptimizeEmlo(problem, emlo, emlo_options);
    ASSERT_TRUE(emlo_result.ok());
    EXPECT_LT(emlo_result->energy, emlo_result->initial_energy);
    BoundaryBasedOptions bb_options;
    bb_options.guard = ConnectivityGuardKind::kVertexBoundaryEdgeCount;
    absl::StatusOr<OptimizeResult> bb_result = OptimizeBoundaryBased(problem, bb, bb_options);
    ASSERT_TRUE(bb_result.ok());
    EXPECT_LT(bb_result->energy, bb_result->initial_energy);
    for (const auto* labels : {&emlo, &bb}) {
      EXPECT_EQ(CountClusters(*labels), 200u);
      for (const auto& [c, t] : Topology(l, *labels)) EXPECT_EQ(t.pieces, 1) << file;
    }
    // Without a guard the same runs split clusters: the guard is what keeps them whole.
    EmloOptions off;
    off.guard = ConnectivityGuardKind::kOff;
    ASSERT_TRUE(OptimizeEmlo(problem, free, off).ok());
    int free_pieces = 0;
    for (const auto& [c, t] : Topology(l, free)) free_pieces += t.pieces;
    EXPECT_GT(free_pieces, start_pieces) << file;
  }
}

// A cube split into 12 triangles, clustered into 6 by EMLO with the planar energy: each
// side becomes one cluster and the energy is 0.
TEST(OptimizerTest, CubeGivesSixPlanarClustersOfEnergyZero) {
  // A cube with each side a 3 x 3 grid of squares (108 faces), so seeds can land anywhere.
  const TriangleMesh cube = testing::IntegerCube(3);
  const Loaded l = Load(cube);
  ASSERT_EQ(l.mesh.num_faces(), 108u);
  const MeshProblem problem = l.problem(MeshEnergyKind::kPlanar);
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    absl::StatusOr<std::vector<ClusterId>> labels =
        InitialClusters(problem, {SeedOptions::Method::kLNeighbourhood, 6, 0, seed});
    ASSERT_TRUE(labels.ok()) << labels.status();
    absl::StatusOr<OptimizeResult> result = OptimizeEmlo(problem, *labels);
    ASSERT_TRUE(result.ok());
    EXPECT_NEAR(result->energy, 0.0, 1e-9) << "seed " << seed;
    EXPECT_EQ(CountClusters(*labels), 6u);
  }
}

TEST(OptimizerTest, BadLabelsAreRefused) {
  const Loaded& l = File("elephant.off");
  std::vector<ClusterId> labels(3, ClusterId(0));
  EXPECT_EQ(OptimizeEmlo(l.problem(), labels).status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(OptimizeBoundaryBased(l.problem(), labels).status().code(),
            absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace mlclust

namespace mlclust {
namespace {

// k spherical patches, clustered into k by EMLO with the sphere energy from an
// l-neighbourhood start: the energy falls to that of the true patches (what is left comes
// from triangles that straddle patch borders), far below the start's and one cluster's.
TEST(SphereEnergyTest, SphericalPatchesReachNearZeroEnergyAtK) {
  const testing::SphericalPatchModel model = testing::SphericalPatches(3, 2, 32);
  const Loaded l = Load(model.mesh);  // 6 patches, 12288 faces
  const MeshProblem problem = l.problem(MeshEnergyKind::kSphere);
  const double truth = MeshEnergyOfLabels(problem.energy, l.mesh, model.patch);
  const double one = MeshEnergyOfLabels(problem.energy, l.mesh,
                                        std::vector<ClusterId>(l.mesh.num_faces(), ClusterId(0)));
  absl::StatusOr<std::vector<ClusterId>> labels =
      InitialClusters(problem, {SeedOptions::Method::kLNeighbourhood, 6, 0, 1});
  ASSERT_TRUE(labels.ok()) << labels.status();
  absl::StatusOr<OptimizeResult> result = OptimizeEmlo(problem, *labels);
  ASSERT_TRUE(result.ok());
  std::printf("sphere energy: one cluster %.4g, start %.4g, EMLO %.4g, true patches %.4g\n", one,
              result->initial_energy, result->energy, truth);
  EXPECT_LT(truth, 0.05 * one);  // the model is what it claims to be
  EXPECT_LT(result->energy, 1.1 * truth);
  EXPECT_LT(result->energy, 0.1 * result->initial_energy);
}

TEST(CancellationTest, ASetFlagReturnsCancelledAndLeavesTheLabels) {
  const Loaded& l = File("fandisk.off");
  std::atomic<bool> cancel{true};
  for (auto method : {SeedOptions::Method::kRandom, SeedOptions::Method::kLNeighbourhood}) {
    SeedOptions seeds{method, 50};
    seeds.cancel = &cancel;
    EXPECT_EQ(InitialClusters(l.problem(), seeds).status().code(), absl::StatusCode::kCancelled);
  }
  absl::StatusOr<std::vector<ClusterId>> start =
      InitialClusters(l.problem(), {SeedOptions::Method::kRandom, 50});
  ASSERT_TRUE(start.ok());
  std::vector<ClusterId> labels = *start;
  EmloOptions emlo;
  emlo.cancel = &cancel;
  EXPECT_EQ(OptimizeEmlo(l.problem(), labels, emlo).status().code(), absl::StatusCode::kCancelled);
  EXPECT_EQ(labels, *start);
  BoundaryBasedOptions bb;
  bb.cancel = &cancel;
  EXPECT_EQ(OptimizeBoundaryBased(l.problem(), labels, bb).status().code(),
            absl::StatusCode::kCancelled);
  EXPECT_EQ(labels, *start);
}

TEST(CancellationTest, AFlagSetDuringTheRunStopsIt) {
  // The flag is set from the progress callbacks, in the middle of the work.
  const Loaded& l = File("fandisk.off");
  absl::StatusOr<std::vector<ClusterId>> start =
      InitialClusters(l.problem(), {SeedOptions::Method::kRandom, 50});
  ASSERT_TRUE(start.ok());
  std::atomic<bool> cancel{false};
  std::vector<ClusterId> labels = *start;
  EmloOptions emlo;
  emlo.cancel = &cancel;
  emlo.progress_moves = 1;
  uint64_t reports = 0;
  emlo.on_progress = [&](uint64_t, double) {
    ++reports;
    cancel = true;
  };
  EXPECT_EQ(OptimizeEmlo(l.problem(), labels, emlo).status().code(), absl::StatusCode::kCancelled);
  // EMLO looks at the flag every few thousand faces: it stopped long before converging.
  std::vector<ClusterId> solo = *start;
  absl::StatusOr<OptimizeResult> full = OptimizeEmlo(l.problem(), solo);
  ASSERT_TRUE(full.ok());
  EXPECT_LT(reports, full->moves);
  EXPECT_EQ(labels, *start);

  cancel = false;
  BoundaryBasedOptions bb;
  bb.cancel = &cancel;
  uint32_t sweeps = 0;
  bb.on_iteration = [&](uint32_t, double) {
    ++sweeps;
    cancel = true;
  };
  EXPECT_EQ(OptimizeBoundaryBased(l.problem(), labels, bb).status().code(),
            absl::StatusCode::kCancelled);
  EXPECT_EQ(sweeps, 1u);
}

}  // namespace
}  // namespace mlclust
