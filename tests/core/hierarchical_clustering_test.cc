#include "core/hierarchical_clustering.h"

#include <gtest/gtest.h>

#include "absl/container/flat_hash_map.h"
#include "absl/container/flat_hash_set.h"
#include "core/energies.h"
#include "core/mesh_io.h"
#include "tests/core/test_meshes.h"

namespace mlclust {
namespace {

struct Prepared {
  TriangleMesh mesh;
  FaceAdjacency adjacency;
  FaceMeasures measures;
};

Prepared Prepare(TriangleMesh mesh) {
  Prepared p;
  p.mesh = std::move(mesh);
  EXPECT_TRUE(ValidateMesh(p.mesh).ok()) << ValidateMesh(p.mesh);
  p.adjacency = *BuildFaceAdjacency(p.mesh);
  p.measures = ComputeFaceMeasures(p.mesh);
  return p;
}

// True if every cluster of `labels` is one edge-connected set of faces.
bool ClustersAreConnected(const FaceAdjacency& adjacency, const std::vector<ClusterId>& labels) {
  absl::flat_hash_set<uint32_t> started;
  std::vector<bool> seen(labels.size(), false);
  for (uint32_t f = 0; f < labels.size(); ++f) {
    if (seen[f]) continue;
    if (!started.insert(labels[f].value()).second) return false;  // second piece
    std::vector<uint32_t> stack = {f};
    seen[f] = true;
    while (!stack.empty()) {
      const uint32_t g = stack.back();
      stack.pop_back();
      for (FaceId h : adjacency.neighbours[g]) {
        if (h.valid() && !seen[h.value()] && labels[h.value()] == labels[f]) {
          seen[h.value()] = true;
          stack.push_back(h.value());
        }
      }
    }
  }
  return true;
}

TEST(HierarchicalClusteringTest, TwoTrianglesMergeOnceWithExactCost) {
  const Prepared p = Prepare(testing::TwoTriangles());
  HierarchyLog log;
  auto summary = RunHierarchicalClustering(p.measures, p.adjacency, {}, log);
  ASSERT_TRUE(summary.ok()) << summary.status();
  EXPECT_EQ(summary->levels, 2u);
  EXPECT_EQ(summary->final_clusters, 1u);
  ASSERT_EQ(log.num_levels(), 2u);
  EXPECT_EQ(log.cluster_count(0), 2u);
  EXPECT_EQ(log.cluster_count(1), 1u);
  // Centroids (1/3, 1/3) and (2/3, 2/3), areas 1/2: cost = (1/4) * (2/9) = 1/18.
  EXPECT_NEAR(log.energy(1), 1.0 / 18, 1e-15);
  // Equal sizes: the smaller id keeps its id; face 1 moves from cluster 1 to 0.
  const LevelMoves level = log.level(1);
  ASSERT_EQ(level.element.size(), 1u);
  EXPECT_EQ(level.element[0], 1u);
  EXPECT_EQ(level.to_cluster[0], 0u);
  EXPECT_EQ(level.from_cluster[0], 1u);
}

TEST(HierarchicalClusteringTest, DisconnectedMeshStopsAtOneClusterPerComponent) {
  const Prepared p = Prepare(testing::Grid(4, {1, 5, 9, 13}));  // column 1 removed: 2 parts
  EXPECT_EQ(CountFaceComponents(p.adjacency), 2u);
  HierarchyLog log;
  auto summary = RunHierarchicalClustering(p.measures, p.adjacency, {}, log);
  ASSERT_TRUE(summary.ok());
  EXPECT_EQ(summary->final_clusters, 2u);
  EXPECT_EQ(log.num_levels(), p.mesh.num_faces() - 1);
}

TEST(HierarchicalClusteringTest, MinClustersStopsEarlyAndZeroIsRefused) {
  const Prepared p = Prepare(testing::Grid(10));
  HierarchyLog log;
  auto summary = RunHierarchicalClustering(p.measures, p.adjacency, {.min_clusters = 17}, log);
  ASSERT_TRUE(summary.ok());
  EXPECT_EQ(summary->final_clusters, 17u);
  EXPECT_EQ(log.cluster_count(log.num_levels() - 1), 17u);
  HierarchyLog other;
  EXPECT_EQ(RunHierarchicalClustering(p.measures, p.adjacency, {.min_clusters = 0}, other)
                .status()
                .code(),
            absl::StatusCode::kInvalidArgument);
}

class CancelAfter : public LevelSink {
 public:
  explicit CancelAfter(int levels) : remaining_(levels) {}
  absl::Status OnStart(std::span<const ClusterId>, uint32_t, double) override {
    return absl::OkStatus();
  }
  absl::Status OnLevel(const LevelMoves&) override {
    return --remaining_ > 0 ? absl::OkStatus() : absl::CancelledError("enough");
  }

 private:
  int remaining_;
};

TEST(HierarchicalClusteringTest, SinkErrorStopsTheRun) {
  const Prepared p = Prepare(testing::Grid(10));
  CancelAfter sink(10);
  auto summary = RunHierarchicalClustering(p.measures, p.adjacency, {}, sink);
  EXPECT_EQ(summary.status().code(), absl::StatusCode::kCancelled);
}

// The whole hierarchy of a real mesh: one merge per level, energies that never fall and
// equal the energy recomputed from the rebuilt labels, clusters that stay connected, and
// reconstruction that runs forwards and backwards over every level.
TEST(HierarchicalClusteringTest, WholeHierarchyOfFandiskRebuildsForwardsAndBackwards) {
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(testing::DataPath("fandisk.off"));
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  const Prepared p = Prepare(*std::move(mesh));
  const size_t n = p.mesh.num_faces();
  HierarchyLog log;
  auto summary = RunHierarchicalClustering(p.measures, p.adjacency, {}, log);
  ASSERT_TRUE(summary.ok());
  ASSERT_EQ(log.num_levels(), n);  // n clusters down to 1
  EXPECT_EQ(summary->final_clusters, 1u);
  EXPECT_LT(log.num_moves(), n * 20);  // smaller-into-larger keeps the log O(n log n)
  for (size_t l = 1; l < log.num_levels(); ++l) {
    ASSERT_EQ(log.cluster_count(l), n - l);
    ASSERT_GE(log.energy(l), log.energy(l - 1));
  }

  std::vector<ClusterId> labels(log.start_labels().begin(), log.start_labels().end());
  size_t at = 0;
  for (size_t target : {size_t{1}, n / 2, n - 1000, n - 100, n - 7, n - 1}) {
    ASSERT_TRUE(log.StepLabels(labels, at, target).ok());
    at = target;
    absl::flat_hash_set<uint32_t> distinct;
    for (ClusterId c : labels) distinct.insert(c.value());
    EXPECT_EQ(distinct.size(), log.cluster_count(target)) << target;
    const double direct = CvdEnergyDirect(p.measures, labels);
    EXPECT_NEAR(log.energy(target), direct, 1e-9 * direct + 1e-15) << target;
    EXPECT_TRUE(ClustersAreConnected(p.adjacency, labels)) << target;
  }
  // Backwards to level 0 in one go, then forwards again, match a fresh rebuild.
  ASSERT_TRUE(log.StepLabels(labels, at, 0).ok());
  EXPECT_EQ(labels, SingletonLabels(n));
  ASSERT_TRUE(log.StepLabels(labels, 0, n - 100).ok());
  EXPECT_EQ(labels, *log.LabelsAt(n - 100));
}

}  // namespace
}  // namespace mlclust
