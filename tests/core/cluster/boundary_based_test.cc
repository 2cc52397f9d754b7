// The stages of boundary-based optimisation (core/cluster/boundary_based.h): the one
// conflict rule, and the seam a device decide stage plugs into.
#include "core/cluster/boundary_based.h"

#include <gtest/gtest.h>

#include <atomic>
#include <set>

#include "tests/fixtures/labels.h"
#include "tests/fixtures/test_meshes.h"

namespace mlclust {
namespace {

using boundary_based::kNoMove;

using testing::RawLabels;

std::set<uint32_t> VerticesOf(const TriangleMesh& mesh, uint32_t face) {
  return {mesh.indices[3 * face], mesh.indices[3 * face + 1], mesh.indices[3 * face + 2]};
}

TEST(ResolveConflictsTest, OfFacesSharingAVertexTheSmallerIdWins) {
  const testing::LoadedMesh l = testing::Load(testing::Grid(6));
  const uint32_t n = static_cast<uint32_t>(l.mesh.num_faces());
  const ConnectivityGuard guard(l.mesh, l.adjacency);
  // Two clusters: the left half (x < 3) and the right half; every face proposes the other.
  std::vector<uint32_t> labels(n), sizes(2, 0), target(n);
  for (uint32_t f = 0; f < n; ++f) {
    labels[f] = (f / 2) % 6 < 3 ? 0 : 1;
    ++sizes[labels[f]];
    target[f] = 1 - labels[f];
  }
  // Only every third face proposes; the rest stay.
  for (uint32_t f = 0; f < n; ++f) {
    if (f % 3 != 0) target[f] = kNoMove;
  }
  const boundary_based::StageThreads threads(2);
  boundary_based::ConflictScratch scratch;
  std::vector<uint32_t> accepted;
  boundary_based::ResolveConflicts(guard, /*check_connectivity=*/false, labels, sizes, target,
                                   threads, scratch, accepted);
  ASSERT_FALSE(accepted.empty());
  EXPECT_EQ(accepted.front(), 0u);  // nothing smaller can beat face 0
  EXPECT_TRUE(std::is_sorted(accepted.begin(), accepted.end()));
  // Exactly the proposals with no smaller proposing face around them.
  std::vector<uint32_t> expected;
  for (uint32_t f = 0; f < n; ++f) {
    if (target[f] == kNoMove) continue;
    bool first = true;
    for (uint32_t g = 0; g < f; ++g) {
      if (target[g] == kNoMove) continue;
      for (uint32_t v : VerticesOf(l.mesh, g)) first = first && !VerticesOf(l.mesh, f).count(v);
    }
    if (first) expected.push_back(f);
  }
  EXPECT_EQ(accepted, expected);
  // The same answer on one thread.
  const boundary_based::StageThreads one(1);
  std::vector<uint32_t> accepted_one;
  boundary_based::ResolveConflicts(guard, false, labels, sizes, target, one, scratch, accepted_one);
  EXPECT_EQ(accepted_one, accepted);
}

// A 1 x 3 strip of squares, two triangles each: faces 0..5 form a chain (face i shares an
// edge with i + 1).
const testing::LoadedMesh& Strip() {
  static const testing::LoadedMesh* strip = new testing::LoadedMesh(testing::Load(
      testing::MakeMesh({0, 0, 0, 1, 0, 0, 2, 0, 0, 3, 0, 0, 0, 1, 0, 1, 1, 0, 2, 1, 0, 3, 1, 0},
                        {0, 1, 4, 4, 1, 5, 1, 2, 5, 5, 2, 6, 2, 3, 6, 6, 3, 7})));
  return *strip;
}

TEST(ResolveConflictsTest, TheGuardVetoesAMoveThatWouldSplitACluster) {
  // A 1 x 3 strip of squares, two triangles each: faces 0..5 form a chain (face i shares
  // an edge with i + 1). Cluster 0 = faces 0..2, cluster 1 = faces 3..5.
  const testing::LoadedMesh& l = Strip();
  const ConnectivityGuard guard(l.mesh, l.adjacency);
  const std::vector<uint32_t> labels = {0, 0, 0, 1, 1, 1}, sizes = {3, 3};
  std::vector<uint32_t> target(6, kNoMove);
  target[2] = 1;  // the end of the chain of 0 joins 1: both stay connected
  const boundary_based::StageThreads threads(1);
  boundary_based::ConflictScratch scratch;
  std::vector<uint32_t> accepted;
  boundary_based::ResolveConflicts(guard, true, labels, sizes, target, threads, scratch, accepted);
  EXPECT_EQ(accepted, std::vector<uint32_t>{2});
  target[2] = kNoMove;
  target[1] = 1;  // face 1 leaving would cut face 0 off from face 2
  boundary_based::ResolveConflicts(guard, true, labels, sizes, target, threads, scratch, accepted);
  EXPECT_TRUE(accepted.empty());
  boundary_based::ResolveConflicts(guard, false, labels, sizes, target, threads, scratch, accepted);
  EXPECT_EQ(accepted, std::vector<uint32_t>{1});  // without the guard it goes
}

TEST(ResolveConflictsTest, AProposalTheGuardRefusesDoesNotBlockItsNeighbours) {
  // The strip of the test above. Face 1 proposes to leave cluster 0 (refused: it would cut
  // face 0 off); face 2, which shares a vertex with it, proposes too and is allowed. Face 1
  // must not block face 2: it would block it again every sweep.
  const testing::LoadedMesh& l = Strip();
  const ConnectivityGuard guard(l.mesh, l.adjacency);
  const std::vector<uint32_t> labels = {0, 0, 0, 1, 1, 1}, sizes = {3, 3};
  std::vector<uint32_t> target(6, kNoMove);
  target[1] = 1;
  target[2] = 1;
  const boundary_based::StageThreads threads(2);
  boundary_based::ConflictScratch scratch;
  std::vector<uint32_t> accepted;
  boundary_based::ResolveConflicts(guard, true, labels, sizes, target, threads, scratch, accepted);
  EXPECT_EQ(accepted, std::vector<uint32_t>{2});
  // Without the guard both are allowed, and of the two the smaller id wins.
  boundary_based::ResolveConflicts(guard, false, labels, sizes, target, threads, scratch, accepted);
  EXPECT_EQ(accepted, std::vector<uint32_t>{1});
  // Alg. 3.2 as the check gives the same answer here.
  VertexBoundaryEdgeCountGuard counts(l.mesh, l.adjacency);
  counts.Reset(labels);
  boundary_based::ResolveConflicts(
      guard, [&](uint32_t f, uint32_t to) { return counts.CanMove(f, to, labels, sizes); }, target,
      threads, scratch, accepted);
  EXPECT_EQ(accepted, std::vector<uint32_t>{2});
}

// Runs the sweeps with the given decide stage on elephant-with-holes, CVD, k = 40.
template <typename Decide>
absl::StatusOr<OptimizeResult> RunWith(std::vector<uint32_t>& labels,
                                       const BoundaryBasedOptions& options, Decide&& decide) {
  const testing::LoadedMesh& l = testing::LoadDataFile("elephant-with-holes.off");
  const CvdEnergy energy(l.measures);
  Partition<CvdEnergy> partition(energy, labels, 40);
  const ConnectivityGuard guard(l.mesh, l.adjacency);
  const boundary_based::StageThreads threads(options.threads);
  auto result = boundary_based::RunBoundaryBased(guard, partition, options, threads, decide);
  labels.assign(partition.labels().begin(), partition.labels().end());
  return result;
}

std::vector<uint32_t> StartLabels() {
  const testing::LoadedMesh& l = testing::LoadDataFile("elephant-with-holes.off");
  absl::StatusOr<std::vector<ClusterId>> labels =
      InitialClusters(l.problem(), {SeedOptions::Method::kRandom, 40, 0, 5});
  EXPECT_TRUE(labels.ok());
  return RawLabels(*labels);
}

TEST(RunBoundaryBasedTest, ADecideStagePluggedInGivesWhatOptimizeBoundaryBasedGives) {
  const testing::LoadedMesh& l = testing::LoadDataFile("elephant-with-holes.off");
  std::vector<uint32_t> labels = StartLabels();
  std::vector<ClusterId> reference(labels.size());
  for (size_t f = 0; f < labels.size(); ++f) reference[f] = ClusterId(labels[f]);
  absl::StatusOr<OptimizeResult> expected = OptimizeBoundaryBased(l.problem(), reference);
  ASSERT_TRUE(expected.ok());
  ASSERT_GT(expected->moves, 0u);

  // A "device" stage: the rule face by face, serially, counting its calls.
  const CvdEnergy energy(l.measures);
  int calls = 0;
  auto serial_decide = [&](std::span<const uint32_t> current,
                           std::span<const CvdEnergy::Proxy> proxies, std::span<uint32_t> target) {
    ++calls;
    for (uint32_t f = 0; f < target.size(); ++f) {
      target[f] = boundary_based::DecideBoundaryMove(energy, l.adjacency, current, proxies, f);
    }
    return absl::OkStatus();
  };
  absl::StatusOr<OptimizeResult> result = RunWith(labels, {}, serial_decide);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_EQ(calls, static_cast<int>(result->iterations));
  EXPECT_EQ(result->moves, expected->moves);
  EXPECT_DOUBLE_EQ(result->energy, expected->energy);  // cluster order differs in the sum
  EXPECT_EQ(labels, RawLabels(reference));
}

TEST(RunBoundaryBasedTest, ADecideStagesErrorIsReturnedAndNothingMoves) {
  std::vector<uint32_t> labels = StartLabels();
  const std::vector<uint32_t> before = labels;
  auto failing = [](std::span<const uint32_t>, std::span<const CvdEnergy::Proxy>,
                    std::span<uint32_t>) { return absl::UnavailableError("device lost"); };
  absl::StatusOr<OptimizeResult> result = RunWith(labels, {}, failing);
  EXPECT_EQ(result.status().code(), absl::StatusCode::kUnavailable);
  EXPECT_EQ(labels, before);
}

TEST(RunBoundaryBasedTest, NoProposalsConvergeAfterOneSweep) {
  std::vector<uint32_t> labels = StartLabels();
  auto none = [](std::span<const uint32_t>, std::span<const CvdEnergy::Proxy>,
                 std::span<uint32_t> target) {
    std::fill(target.begin(), target.end(), kNoMove);
    return absl::OkStatus();
  };
  absl::StatusOr<OptimizeResult> result = RunWith(labels, {}, none);
  ASSERT_TRUE(result.ok());
  EXPECT_TRUE(result->converged);
  EXPECT_EQ(result->iterations, 1u);
  EXPECT_EQ(result->moves, 0u);
  EXPECT_EQ(result->energy, result->initial_energy);
}

TEST(RunBoundaryBasedTest, ACancelledRunStopsBeforeTheNextStage) {
  std::vector<uint32_t> labels = StartLabels();
  std::atomic<bool> cancel{false};
  BoundaryBasedOptions options;
  options.cancel = &cancel;
  int calls = 0;
  auto cancelling = [&](std::span<const uint32_t>, std::span<const CvdEnergy::Proxy>,
                        std::span<uint32_t> target) {
    ++calls;
    std::fill(target.begin(), target.end(), kNoMove);
    cancel = true;  // set while deciding: the run must stop before resolving
    return absl::OkStatus();
  };
  absl::StatusOr<OptimizeResult> result = RunWith(labels, options, cancelling);
  EXPECT_EQ(result.status().code(), absl::StatusCode::kCancelled);
  EXPECT_EQ(calls, 1);
}

TEST(RunBoundaryBasedTest, AlgThreeTwoWithoutCountsIsRefusedAndWithThemMatchesTheRingTest) {
  const testing::LoadedMesh& l = testing::LoadDataFile("elephant-with-holes.off");
  auto decide_with = [&](const CvdEnergy& energy) {
    return [&](std::span<const uint32_t> current, std::span<const CvdEnergy::Proxy> proxies,
               std::span<uint32_t> target) {
      for (uint32_t f = 0; f < target.size(); ++f) {
        target[f] = boundary_based::DecideBoundaryMove(energy, l.adjacency, current, proxies, f);
      }
      return absl::OkStatus();
    };
  };
  const CvdEnergy energy(l.measures);
  BoundaryBasedOptions options;
  options.guard = ConnectivityGuardKind::kVertexBoundaryEdgeCount;
  std::vector<uint32_t> labels = StartLabels();
  const std::vector<uint32_t> before = labels;
  absl::StatusOr<OptimizeResult> refused = RunWith(labels, options, decide_with(energy));
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(labels, before);
  // With the counts: every cluster stays in one piece and the energy falls.
  Partition<CvdEnergy> partition(energy, before, 40);
  const ConnectivityGuard rings(l.mesh, l.adjacency);
  VertexBoundaryEdgeCountGuard counts(l.mesh, l.adjacency);
  const boundary_based::StageThreads threads(2);
  absl::StatusOr<OptimizeResult> result = boundary_based::RunBoundaryBased(
      rings, &counts, partition, options, threads, decide_with(energy));
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_GT(result->moves, 0u);
  EXPECT_LT(result->energy, result->initial_energy);
  // The counts were kept: they equal counts computed afresh from the final labels.
  VertexBoundaryEdgeCountGuard fresh(l.mesh, l.adjacency);
  fresh.Reset(partition.labels());
  for (uint32_t v = 0; v < l.mesh.num_vertices(); ++v) {
    ASSERT_EQ(counts.count(v), fresh.count(v)) << "vertex " << v;
  }
}

}  // namespace
}  // namespace mlclust
