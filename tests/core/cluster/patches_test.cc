// Meshlet-sized patches (core/cluster/patches.h): spread seeds, and the whole route.
#include "core/cluster/patches.h"

#include <gtest/gtest.h>

#include <atomic>
#include <set>

#include "core/cluster/registry.h"
#include "core/hierarchy/hierarchy.h"
#include "core/mesh/connectivity_guard.h"
#include "core/plan/device_policy.h"
#include "tests/fixtures/test_meshes.h"

namespace mlclust {
namespace {

using testing::PiecesPerCluster;

// Two copies of a mesh side by side: two connected components.
TriangleMesh TwoCopies(const TriangleMesh& mesh, float shift) {
  TriangleMesh both = mesh;
  const uint32_t offset = static_cast<uint32_t>(mesh.num_vertices());
  for (size_t v = 0; v < mesh.num_vertices(); ++v) {
    both.positions.push_back(mesh.positions[3 * v] + shift);
    both.positions.push_back(mesh.positions[3 * v + 1]);
    both.positions.push_back(mesh.positions[3 * v + 2]);
  }
  for (uint32_t i : mesh.indices) both.indices.push_back(i + offset);
  return both;
}

TEST(SpreadSeedsTest, GivesKDistinctSeedsAndOnePerComponentAtLeast) {
  // A small cube and a large one: 6 * 2 * 4 = 48 and 6 * 2 * 64 = 768 faces.
  TriangleMesh small = testing::MakeCube(2).mesh;
  TriangleMesh mesh = testing::MakeCube(8).mesh;
  const uint32_t offset = static_cast<uint32_t>(mesh.num_vertices());
  for (size_t v = 0; v < small.num_vertices(); ++v) {
    mesh.positions.push_back(small.positions[3 * v] + 3.0f);
    mesh.positions.push_back(small.positions[3 * v + 1]);
    mesh.positions.push_back(small.positions[3 * v + 2]);
  }
  for (uint32_t i : small.indices) mesh.indices.push_back(i + offset);
  const testing::LoadedMesh l = testing::Load(std::move(mesh));
  const MeshProblem problem = l.problem();
  for (uint32_t k : {2u, 3u, 17u, 100u, 816u}) {
    absl::StatusOr<std::vector<FaceId>> seeds = SpreadSeeds(problem, k);
    ASSERT_TRUE(seeds.ok()) << seeds.status();
    ASSERT_EQ(seeds->size(), k);
    std::set<uint32_t> distinct;
    uint32_t in_small = 0;
    for (FaceId f : *seeds) {
      distinct.insert(f.value());
      in_small += f.value() >= 768;
    }
    EXPECT_EQ(distinct.size(), k);
    EXPECT_GE(in_small, 1u) << k;
    EXPECT_LT(in_small, k) << k;
    // Shared by face counts (48 of 816): the small cube gets about k * 47 / 814 of the rest.
    EXPECT_LE(in_small, 1 + (k - 2) * 47 / 814 + 1) << k;
  }
}

TEST(SpreadSeedsTest, RefusesKOutOfRange) {
  const testing::LoadedMesh l = testing::Load(TwoCopies(testing::Tetrahedron(), 5.0f));
  const MeshProblem problem = l.problem();
  EXPECT_EQ(SpreadSeeds(problem, 0).status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(SpreadSeeds(problem, 9).status().code(), absl::StatusCode::kInvalidArgument);
  // Two components: one patch cannot hold both.
  absl::Status one = SpreadSeeds(problem, 1).status();
  EXPECT_EQ(one.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(one.message().find("components"), std::string::npos) << one;
  EXPECT_TRUE(SpreadSeeds(problem, 2).ok());
  EXPECT_TRUE(SpreadSeeds(problem, 8).ok());
}

TEST(SpreadSeedsTest, SeedsAreSpreadOverTheSurface) {
  // On a 16 x 16 cube (3072 faces) with 6 seeds, Morton runs of 512 faces: at least half
  // of the sides get a seed (a curve through space does not follow the sides exactly).
  const testing::SubdividedCube cube = testing::MakeCube(16);
  const testing::LoadedMesh l = testing::Load(cube.mesh);
  absl::StatusOr<std::vector<FaceId>> seeds = SpreadSeeds(l.problem(), 6);
  ASSERT_TRUE(seeds.ok());
  std::set<int> sides;
  for (FaceId f : *seeds) sides.insert(cube.side[f.value()]);
  EXPECT_GE(sides.size(), 3u);
  // The seeds are at least two squares apart from each other.
  for (size_t a = 0; a < seeds->size(); ++a) {
    for (size_t b = a + 1; b < seeds->size(); ++b) {
      const Vec3 d =
          l.measures.centroid[(*seeds)[a].value()] - l.measures.centroid[(*seeds)[b].value()];
      EXPECT_GT(d.x * d.x + d.y * d.y + d.z * d.z, (2.0 / 16) * (2.0 / 16)) << a << " " << b;
    }
  }
}

struct PatchCase {
  const char* mesh;
  uint32_t clusters;
};

class BuildPatchesTest : public ::testing::TestWithParam<PatchCase> {};

TEST_P(BuildPatchesTest, ReachesKWithConnectedPatchesAndLowersTheEnergy) {
  const testing::LoadedMesh& l = testing::LoadDataFile(GetParam().mesh);
  const MeshProblem problem = l.problem();
  const uint32_t k = GetParam().clusters;
  PatchOptions options;
  options.clusters = k;
  options.threads = 2;
  absl::StatusOr<PatchResult> result = BuildPatches(problem, options);
  ASSERT_TRUE(result.ok()) << result.status();
  for (const std::vector<ClusterId>* labels : {&result->initial_labels, &result->labels}) {
    ASSERT_EQ(labels->size(), l.mesh.num_faces());
    std::set<uint32_t> used;
    for (ClusterId c : *labels) {
      ASSERT_LT(c.value(), k);
      used.insert(c.value());
    }
    EXPECT_EQ(used.size(), k);  // K reached, no patch empty
    const std::vector<uint32_t> pieces = PiecesPerCluster(l.adjacency, *labels, k);
    for (uint32_t c = 0; c < k; ++c) EXPECT_EQ(pieces[c], 1u) << "patch " << c;
  }
  EXPECT_GT(result->sweeps, 0u);
  EXPECT_GT(result->moves, 0u);
  EXPECT_LT(result->energy, result->initial_energy);
  // The energies are the partitions' own.
  EXPECT_NEAR(result->initial_energy,
              MeshEnergyOfLabels(problem.energy, l.mesh, result->initial_labels),
              1e-9 * result->initial_energy);
  EXPECT_NEAR(result->energy, MeshEnergyOfLabels(problem.energy, l.mesh, result->labels),
              1e-9 * result->energy);
}

INSTANTIATE_TEST_SUITE_P(Meshes, BuildPatchesTest,
                         ::testing::Values(PatchCase{"fandisk.off", 12946 / 124},
                                           PatchCase{"elephant.off", 40},
                                           PatchCase{"elephant-with-holes.off", 60}),
                         [](const ::testing::TestParamInfo<PatchCase>& info) {
                           std::string name = info.param.mesh;
                           for (char& c : name) {
                             if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                           }
                           return name;
                         });

TEST(BuildPatchesTest, MoreSweepsNeverRaiseTheEnergyAndTheResultIsDeterministic) {
  const testing::LoadedMesh& l = testing::LoadDataFile("fandisk.off");
  PatchOptions options;
  options.clusters = 104;
  double previous = std::numeric_limits<double>::infinity();
  for (uint32_t sweeps : {0u, 1u, 2u, 4u, 8u, 16u}) {
    options.sweeps = sweeps;
    absl::StatusOr<PatchResult> result = BuildPatches(l.problem(), options);
    ASSERT_TRUE(result.ok());
    EXPECT_LE(result->energy, previous) << sweeps;
    EXPECT_LE(result->sweeps, sweeps);
    if (sweeps == 0) EXPECT_EQ(result->labels, result->initial_labels);
    previous = result->energy;
    // Thread counts give the same patches: decisions are per face, moves in face order.
    PatchOptions one_thread = options;
    one_thread.threads = 1;
    absl::StatusOr<PatchResult> again = BuildPatches(l.problem(), one_thread);
    ASSERT_TRUE(again.ok());
    EXPECT_EQ(again->labels, result->labels) << sweeps;
  }
}

TEST(BuildPatchesTest, ALloydStepOnTheSeedsLowersTheGrownEnergy) {
  const testing::LoadedMesh& l = testing::LoadDataFile("fandisk.off");
  PatchOptions options;
  options.clusters = 104;
  options.sweeps = 0;
  options.reseeds = 0;
  absl::StatusOr<PatchResult> plain = BuildPatches(l.problem(), options);
  options.reseeds = 1;
  absl::StatusOr<PatchResult> moved = BuildPatches(l.problem(), options);
  ASSERT_TRUE(plain.ok() && moved.ok());
  EXPECT_LT(moved->energy, plain->energy);
}

TEST(BuildPatchesTest, RefusesAndCancels) {
  const testing::LoadedMesh& l = testing::LoadDataFile("fandisk.off");
  PatchOptions options;
  options.clusters = 0;
  EXPECT_EQ(BuildPatches(l.problem(), options).status().code(), absl::StatusCode::kInvalidArgument);
  options.clusters = 10;
  options.threads = -1;
  EXPECT_EQ(BuildPatches(l.problem(), options).status().code(), absl::StatusCode::kInvalidArgument);
  options.threads = 0;
  std::atomic<bool> cancel{true};
  options.cancel = &cancel;
  EXPECT_EQ(BuildPatches(l.problem(), options).status().code(), absl::StatusCode::kCancelled);
}

const testing::LoadedMesh& ElephantWithHoles() {
  return testing::LoadDataFile("elephant-with-holes.off");
}

PatchOptions Patches(uint32_t clusters, uint32_t sweeps) {
  PatchOptions options;
  options.clusters = clusters;
  options.sweeps = sweeps;
  return options;
}

// The face-order apply keeps patches connected where BB's guard would: on a mesh with
// holes, many patches, many sweeps.
TEST(BuildPatchesTest, GuardKeepsEveryPatchConnectedOverManySweeps) {
  const testing::LoadedMesh& l = ElephantWithHoles();
  absl::StatusOr<PatchResult> result = BuildPatches(l.problem(), Patches(150, 50));
  ASSERT_TRUE(result.ok());
  const std::vector<uint32_t> pieces = PiecesPerCluster(l.adjacency, result->labels, 150);
  for (uint32_t c = 0; c < 150; ++c) EXPECT_EQ(pieces[c], 1u) << "patch " << c;
}

// The rings built on demand (BuildFaceRing, RingTestAllows: what the sweeps ask) answer
// as ConnectivityGuard's stored rings do, on a mesh with holes (rings broken by the
// boundary) and patches of every shape the growth makes.
TEST(BuildPatchesTest, OnDemandRingTestIsTheGuards) {
  const testing::LoadedMesh& l = ElephantWithHoles();
  absl::StatusOr<PatchResult> grown = BuildPatches(l.problem(), Patches(300, 0));
  ASSERT_TRUE(grown.ok());
  std::vector<uint32_t> labels, sizes(300, 0);
  for (ClusterId c : grown->initial_labels) {
    labels.push_back(c.value());
    ++sizes[c.value()];
  }
  const ConnectivityGuard guard(l.mesh, l.adjacency);
  std::vector<uint32_t> ring;
  int allowed = 0, refused = 0;
  for (uint32_t f = 0; f < labels.size(); ++f) {
    for (FaceId g : l.adjacency.neighbours[f]) {
      if (!g.valid() || labels[g.value()] == labels[f]) continue;
      const uint32_t to = labels[g.value()];
      BuildFaceRing(l.mesh, l.adjacency, f, ring);
      const bool on_demand = sizes[labels[f]] > 1 && RingTestAllows(ring, labels[f], to, labels);
      ASSERT_EQ(on_demand, guard.CanMove(f, to, labels, sizes)) << "face " << f;
      (on_demand ? allowed : refused) += 1;
    }
  }
  EXPECT_GT(allowed, 100);
  EXPECT_GT(refused, 100);
}

// BB's preset "patches" through the registry: the two levels are the grown seeds and the
// patches, K each.
TEST(BuildPatchesTest, RunsAsBbPresetThroughTheRegistry) {
  const testing::LoadedMesh& l = testing::LoadDataFile("fandisk.off");
  JobRequest request;
  request.algorithm = FindAlgorithm(InputKind::kMesh, "bb");
  ASSERT_NE(request.algorithm, nullptr);
  request.clusters = 104;
  request.options = {{"preset", "patches"}, {"patch-sweeps", "3"}, {"threads", "2"}};
  absl::StatusOr<JobPlan> plan = PlanJob(request);
  ASSERT_TRUE(plan.ok()) << plan.status();
  ASSERT_TRUE(PlanDevices(DeviceCaps{}, *plan).ok());
  HierarchyLog log;
  const MeshProblem problem = l.problem();
  absl::StatusOr<RunSummary> summary = plan->algorithm->run_mesh(problem, *plan, log, {});
  ASSERT_TRUE(summary.ok()) << summary.status();
  ASSERT_EQ(log.num_levels(), 2u);
  EXPECT_EQ(log.cluster_count(0), 104u);
  EXPECT_EQ(log.cluster_count(1), 104u);
  EXPECT_LE(log.energy(1), log.energy(0));
  PatchOptions options;
  options.clusters = 104;
  options.sweeps = 3;
  absl::StatusOr<PatchResult> direct = BuildPatches(problem, options);
  ASSERT_TRUE(direct.ok());
  EXPECT_DOUBLE_EQ(log.energy(1), direct->energy);
  // vertex-count is BB's Alg. 3.2 guard, which the preset does not run.
  request.options.push_back({"guard", "vertex-count"});
  plan = PlanJob(request);
  ASSERT_TRUE(plan.ok());
  HierarchyLog refused;
  EXPECT_EQ(plan->algorithm->run_mesh(problem, *plan, refused, {}).status().code(),
            absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace mlclust
