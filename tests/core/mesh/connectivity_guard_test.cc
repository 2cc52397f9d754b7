#include "core/mesh/connectivity_guard.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <deque>
#include <random>
#include <set>
#include <vector>

#include "core/mesh/cluster_pieces.h"
#include "tests/fixtures/test_meshes.h"

namespace mlclust {
namespace {

// Grid(n): square (x, y) has the faces 2 (y n + x) (corners (x,y), (x+1,y), (x,y+1)) and
// 2 (y n + x) + 1 (corners (x,y+1), (x+1,y), (x+1,y+1)); vertex (x, y) is y (n + 1) + x.
uint32_t Lower(int n, int x, int y) { return 2 * (y * n + x); }
uint32_t Upper(int n, int x, int y) { return 2 * (y * n + x) + 1; }
uint32_t VertexAt(int n, int x, int y) { return y * (n + 1) + x; }

struct Clustered {
  TriangleMesh mesh;
  FaceAdjacency adjacency;
  std::vector<uint32_t> labels;
  std::vector<uint32_t> sizes;

  explicit Clustered(TriangleMesh m) : mesh(std::move(m)) {
    EXPECT_TRUE(ValidateMesh(mesh).ok());
    adjacency = *BuildFaceAdjacency(mesh);
  }
  void Label(std::vector<uint32_t> l, uint32_t k) {
    labels = std::move(l);
    sizes.assign(k, 0);
    for (uint32_t c : labels) ++sizes[c];
  }
};

// Labels by square: cluster_of(x, y) for both faces of square (x, y).
template <typename F>
std::vector<uint32_t> BySquare(int n, F cluster_of) {
  std::vector<uint32_t> labels(2 * n * n);
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      labels[Lower(n, x, y)] = labels[Upper(n, x, y)] = cluster_of(x, y);
    }
  }
  return labels;
}

// V - E + F of each cluster's faces (1 for a disc, 0 for an annulus).
std::vector<int64_t> EulerCharacteristics(const TriangleMesh& mesh, const FaceAdjacency& adjacency,
                                          const std::vector<uint32_t>& labels, uint32_t k) {
  std::vector<int64_t> chi(k, 0);
  std::set<std::pair<uint32_t, uint32_t>> vertices;  // (cluster, vertex)
  for (uint32_t f = 0; f < labels.size(); ++f) {
    chi[labels[f]] += 1;
    for (int e = 0; e < 3; ++e) {
      const FaceId h = adjacency.neighbours[f][e];
      if (!(h.valid() && labels[h.value()] == labels[f] && h.value() < f)) chi[labels[f]] -= 1;
      if (vertices.insert({labels[f], mesh.indices[3 * f + e]}).second) chi[labels[f]] += 1;
    }
  }
  return chi;
}

// Grid(n) labelled by square (cluster_of, k clusters) with a vertex-count guard reset to
// the labels.
struct GuardedGrid : Clustered {
  template <typename F>
  GuardedGrid(int n, F cluster_of, uint32_t k)
      : Clustered(testing::Grid(n)), guard(mesh, adjacency) {
    Label(BySquare(n, cluster_of), k);
    guard.Reset(labels);
  }
  VertexBoundaryEdgeCountGuard guard;
};

TEST(VertexBoundaryEdgeCountTest, CountsAreTheBoundaryEdgesAtEachVertex) {
  const int n = 4;
  GuardedGrid s(
      n, [](int x, int) { return x < 2 ? 0u : 1u; }, 2);
  VertexBoundaryEdgeCountGuard& guard = s.guard;
  // Interior vertex on the vertical border x = 2: the two border edges above and below it.
  EXPECT_EQ(guard.count(VertexAt(n, 2, 2)), 2u);
  // Interior vertex inside a cluster: none.
  EXPECT_EQ(guard.count(VertexAt(n, 1, 2)), 0u);
  // Corner of the grid: its two mesh border edges.
  EXPECT_EQ(guard.count(VertexAt(n, 0, 0)), 2u);
  // Where the cluster border meets the mesh border: two border edges and the cluster edge.
  EXPECT_EQ(guard.count(VertexAt(n, 2, 0)), 3u);
}

// Case 0 (Fig. 3.9): V2 has no boundary edge, so growing is allowed; afterwards
// count(V2) = 2 and V1, V3 keep their counts, as the text's update says.
TEST(VertexBoundaryEdgeCountTest, CaseZeroIsAllowedAndUpdatesV2ToTwo) {
  const int n = 6;
  GuardedGrid s(
      n, [](int x, int) { return x < 3 ? 0u : 1u; }, 2);
  VertexBoundaryEdgeCountGuard& guard = s.guard;
  const ConnectivityGuard ring(s.mesh, s.adjacency);
  // The lower face of square (3, 2) crosses the border x = 3 with its edge (3,3) -> (3,2):
  // V1 = (3, 3), V3 = (3, 2), V2 = (4, 2).
  const uint32_t face = Lower(n, 3, 2);
  const uint32_t v1 = VertexAt(n, 3, 3), v2 = VertexAt(n, 4, 2), v3 = VertexAt(n, 3, 2);
  ASSERT_EQ(guard.count(v2), 0u);
  const uint32_t v1_before = guard.count(v1), v3_before = guard.count(v3);
  EXPECT_TRUE(guard.CanMove(face, 0, s.labels, s.sizes));
  EXPECT_TRUE(ring.CanMove(face, 0, s.labels, s.sizes));
  s.labels[face] = 0;
  guard.OnMove(face, 1, s.labels);
  EXPECT_EQ(guard.count(v2), 2u);
  EXPECT_EQ(guard.count(v1), v1_before);
  EXPECT_EQ(guard.count(v3), v3_before);
}

// Fig. 3.9 (b): taking a face out of a one-face-wide strip would split the strip.
TEST(VertexBoundaryEdgeCountTest, RejectsSplittingAStrip) {
  const int n = 6;
  GuardedGrid s(
      n, [](int, int y) { return y < 2    ? 0u
                                 : y == 2 ? 1u
                                          : 2u; }, 3);
  VertexBoundaryEdgeCountGuard& guard = s.guard;
  const ConnectivityGuard ring(s.mesh, s.adjacency);
  const uint32_t face = Lower(n, 3, 2);  // in the strip, its bottom edge on cluster 0
  EXPECT_FALSE(guard.CanMove(face, 0, s.labels, s.sizes));
  EXPECT_FALSE(ring.CanMove(face, 0, s.labels, s.sizes));
  // Without a guard the strip would indeed split.
  s.labels[face] = 0;
  EXPECT_EQ(ClusterPieces(s.adjacency, s.labels, 3)[1], 2u);
}

// Fig. 3.9 (c): closing a ring of the current cluster around a region (the current cluster
// would get a hole; here the enclosed square is also cut off from its cluster).
TEST(VertexBoundaryEdgeCountTest, RejectsClosingARing) {
  const int n = 7;
  Clustered s(testing::Grid(n));
  // Cluster 1: the squares around (3, 3), the centre square (3, 3) itself is cluster 0.
  s.Label(BySquare(n,
                   [](int x, int y) {
                     const bool around = x >= 2 && x <= 4 && y >= 2 && y <= 4;
                     return around && !(x == 3 && y == 3) ? 1u : 0u;
                   }),
          2);
  // Open the ring at square (3, 2): cluster 0 reaches the centre there. Its upper face,
  // given to cluster 1, would close the ring (and cut the centre off).
  s.labels[Lower(n, 3, 2)] = s.labels[Upper(n, 3, 2)] = 0;
  s.Label(s.labels, 2);
  const uint32_t gap = Upper(n, 3, 2);
  ASSERT_EQ(ClusterPieces(s.adjacency, s.labels, 2), (std::vector<uint32_t>{1, 1}));
  VertexBoundaryEdgeCountGuard guard(s.mesh, s.adjacency);
  guard.Reset(s.labels);
  const ConnectivityGuard ring(s.mesh, s.adjacency);
  EXPECT_FALSE(guard.CanMove(gap, 1, s.labels, s.sizes));
  EXPECT_FALSE(ring.CanMove(gap, 1, s.labels, s.sizes));
}

// Fig. 3.9 (a): a cluster's last face stays.
TEST(VertexBoundaryEdgeCountTest, RejectsDeletingACluster) {
  const int n = 3;
  Clustered s(testing::Grid(n));
  std::vector<uint32_t> labels(2 * n * n, 0);
  labels[Lower(n, 1, 1)] = 1;
  s.Label(labels, 2);
  VertexBoundaryEdgeCountGuard guard(s.mesh, s.adjacency);
  guard.Reset(s.labels);
  EXPECT_FALSE(guard.CanMove(Lower(n, 1, 1), 0, s.labels, s.sizes));
}

// Random moves on real meshes, from clusters grown breadth-first (edge-connected; around
// the mesh's holes not discs): the O(1) updates keep the counts equal to a recount, every
// cluster stays connected under Alg. 3.2, none gains a hole, and every move the ring test
// allows Alg. 3.2 allows too (it allows more where clusters are not discs; BENCHMARKS.md).
TEST(VertexBoundaryEdgeCountTest, RandomMovesKeepCountsExactAndClustersConnected) {
  for (const char* name : {"elephant-with-holes.off", "fandisk.off"}) {
    const testing::LoadedMesh& loaded = testing::LoadDataFile(name);
    Clustered s(loaded.mesh);
    const uint32_t faces = static_cast<uint32_t>(s.mesh.num_faces());
    const uint32_t k = 60;
    // Breadth-first growth from k seeds.
    std::vector<uint32_t> labels(faces, k);
    std::deque<uint32_t> queue;
    std::mt19937 rng(7);
    for (uint32_t c = 0; c < k; ++c) {
      uint32_t f = rng() % faces;
      while (labels[f] != k) f = rng() % faces;
      labels[f] = c;
      queue.push_back(f);
    }
    while (!queue.empty()) {
      const uint32_t f = queue.front();
      queue.pop_front();
      for (FaceId h : s.adjacency.neighbours[f]) {
        if (h.valid() && labels[h.value()] == k) {
          labels[h.value()] = labels[f];
          queue.push_back(h.value());
        }
      }
    }
    s.Label(labels, k);
    ASSERT_EQ(ClusterPieces(s.adjacency, s.labels, k), std::vector<uint32_t>(k, 1)) << name;
    VertexBoundaryEdgeCountGuard guard(s.mesh, s.adjacency);
    guard.Reset(s.labels);
    const ConnectivityGuard ring(s.mesh, s.adjacency);
    const std::vector<int64_t> euler_before =
        EulerCharacteristics(s.mesh, s.adjacency, s.labels, k);
    int moves = 0, ring_only = 0;
    for (int trial = 0; trial < 200000; ++trial) {
      const uint32_t f = rng() % faces;
      const FaceId across = s.adjacency.neighbours[f][rng() % 3];
      if (!across.valid() || s.labels[across.value()] == s.labels[f]) continue;
      const uint32_t to = s.labels[across.value()];
      const bool allowed = guard.CanMove(f, to, s.labels, s.sizes);
      ring_only += !allowed && ring.CanMove(f, to, s.labels, s.sizes);
      // The stateless form (no counts) decides the same on every proposal.
      ASSERT_EQ(guard.CanMoveWithoutCounts(f, to, s.labels, s.sizes), allowed)
          << name << " face " << f << " to " << to;
      if (!allowed) continue;
      const uint32_t from = s.labels[f];
      s.labels[f] = to;
      --s.sizes[from];
      ++s.sizes[to];
      guard.OnMove(f, from, s.labels);
      ++moves;
    }
    EXPECT_GT(moves, 1000) << name;
    EXPECT_EQ(ring_only, 0) << name;
    EXPECT_EQ(ClusterPieces(s.adjacency, s.labels, k), std::vector<uint32_t>(k, 1)) << name;
    // No cluster gained a hole or a handle (a cluster around one of the mesh's holes may
    // lose it: Alg. 3.2 lets it give the hole's rim away, which the ring test does not).
    const std::vector<int64_t> euler_after = EulerCharacteristics(s.mesh, s.adjacency, s.labels, k);
    for (uint32_t c = 0; c < k; ++c) EXPECT_GE(euler_after[c], euler_before[c]) << name << " " << c;
    VertexBoundaryEdgeCountGuard recount(s.mesh, s.adjacency);
    recount.Reset(s.labels);
    for (uint32_t v = 0; v < s.mesh.num_vertices(); ++v) {
      ASSERT_EQ(guard.count(v), recount.count(v)) << name << " vertex " << v;
    }
  }
}

}  // namespace
}  // namespace mlclust
