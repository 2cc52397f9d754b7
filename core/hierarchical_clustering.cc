#include "core/hierarchical_clustering.h"

#include <algorithm>
#include <numeric>
#include <queue>

#include "absl/strings/str_cat.h"
#include "core/energies.h"

namespace mlclust {
namespace {

// A candidate merge (a dual edge between clusters a < b) as it was when pushed. It is
// stale once either cluster has changed since: lazy invalidation by version numbers
// replaces a decrease-key heap.
struct DualEdge {
  double cost;
  uint32_t a, b;
  uint32_t version_a, version_b;
};

struct CheaperLast {
  bool operator()(const DualEdge& x, const DualEdge& y) const {
    if (x.cost != y.cost) return x.cost > y.cost;
    if (x.a != y.a) return x.a > y.a;
    return x.b > y.b;
  }
};

Vec3 BoundingBoxCentre(const FaceMeasures& measures) {
  if (measures.num_faces() == 0) return {};
  Vec3 lo = measures.centroid[0], hi = lo;
  for (const Vec3& g : measures.centroid) {
    lo = {std::min(lo.x, g.x), std::min(lo.y, g.y), std::min(lo.z, g.z)};
    hi = {std::max(hi.x, g.x), std::max(hi.y, g.y), std::max(hi.z, g.z)};
  }
  return (lo + hi) * 0.5;
}

// Kahan summation keeps the running energy (a sum of up to n merge costs) accurate.
class CompensatedSum {
 public:
  void Add(double x) {
    const double y = x - compensation_;
    const double t = sum_ + y;
    compensation_ = (t - sum_) - y;
    sum_ = t;
  }
  double value() const { return sum_; }

 private:
  double sum_ = 0, compensation_ = 0;
};

}  // namespace

std::vector<ClusterId> SingletonLabels(size_t num_faces) {
  std::vector<ClusterId> labels(num_faces);
  for (size_t i = 0; i < num_faces; ++i) labels[i] = ClusterId(static_cast<uint32_t>(i));
  return labels;
}

absl::StatusOr<HierarchicalClusteringSummary> RunHierarchicalClustering(
    const FaceMeasures& measures, const FaceAdjacency& adjacency,
    const HierarchicalClusteringOptions& options, LevelSink& sink) {
  const size_t n = measures.num_faces();
  if (adjacency.num_faces() != n) {
    return absl::InvalidArgumentError(
        absl::StrCat("adjacency has ", adjacency.num_faces(), " faces, the measures ", n));
  }
  if (options.min_clusters < 1) {
    return absl::InvalidArgumentError("min_clusters must be at least 1");
  }

  // Per-cluster state, indexed by cluster id (= the id of one of its faces).
  const Vec3 origin = BoundingBoxCentre(measures);
  std::vector<CvdSums> sums(n);
  std::vector<std::vector<uint32_t>> members(n);
  std::vector<std::vector<uint32_t>> neighbours(n);
  std::vector<uint32_t> version(n, 0);
  std::vector<bool> alive(n, true);
  for (uint32_t f = 0; f < n; ++f) {
    sums[f] = CvdFaceSums(measures.area[f], measures.centroid[f], origin);
    members[f] = {f};
    for (FaceId g : adjacency.neighbours[f]) {
      if (!g.valid() || g.value() == f) continue;
      auto& list = neighbours[f];
      if (std::find(list.begin(), list.end(), g.value()) == list.end()) list.push_back(g.value());
    }
  }

  std::vector<DualEdge> initial;
  initial.reserve(3 * n / 2 + 1);
  for (uint32_t a = 0; a < n; ++a) {
    for (uint32_t b : neighbours[a]) {
      if (a < b) initial.push_back({CvdMergeCost(sums[a], sums[b]), a, b, 0, 0});
    }
  }
  std::priority_queue<DualEdge, std::vector<DualEdge>, CheaperLast> heap(CheaperLast{},
                                                                         std::move(initial));

  const std::vector<ClusterId> start = SingletonLabels(n);
  if (absl::Status s = sink.OnStart(start, static_cast<uint32_t>(n), 0.0); !s.ok()) return s;

  HierarchicalClusteringSummary summary;
  summary.levels = 1;
  uint32_t clusters = static_cast<uint32_t>(n);
  CompensatedSum energy;
  std::vector<uint32_t> moved_faces, to_cluster, from_cluster;
  std::vector<uint32_t> mark(n, 0);  // scratch for merging neighbour lists
  uint32_t mark_stamp = 0;

  while (clusters > options.min_clusters && !heap.empty()) {
    const DualEdge edge = heap.top();
    heap.pop();
    if (!alive[edge.a] || !alive[edge.b] || version[edge.a] != edge.version_a ||
        version[edge.b] != edge.version_b) {
      continue;
    }
    // The larger cluster keeps its id so that the fewest faces move.
    uint32_t keep = edge.a, gone = edge.b;
    if (members[gone].size() > members[keep].size()) std::swap(keep, gone);

    moved_faces = members[gone];
    to_cluster.assign(moved_faces.size(), keep);
    from_cluster.assign(moved_faces.size(), gone);
    members[keep].insert(members[keep].end(), members[gone].begin(), members[gone].end());
    std::vector<uint32_t>().swap(members[gone]);

    energy.Add(edge.cost);
    sums[keep] += sums[gone];
    alive[gone] = false;
    ++version[keep];
    --clusters;

    // Neighbours of the union: both lists without the pair itself; every neighbour of
    // `gone` now borders `keep` instead.
    ++mark_stamp;
    mark[keep] = mark_stamp;
    std::vector<uint32_t> merged;
    merged.reserve(neighbours[keep].size() + neighbours[gone].size());
    for (uint32_t c : neighbours[keep]) {
      if (c != gone && mark[c] != mark_stamp) {
        mark[c] = mark_stamp;
        merged.push_back(c);
      }
    }
    for (uint32_t c : neighbours[gone]) {
      if (c == keep) continue;
      auto& list = neighbours[c];
      const bool borders_keep = mark[c] == mark_stamp;
      if (borders_keep) {
        list.erase(std::find(list.begin(), list.end(), gone));
      } else {
        *std::find(list.begin(), list.end(), gone) = keep;
        mark[c] = mark_stamp;
        merged.push_back(c);
      }
    }
    std::vector<uint32_t>().swap(neighbours[gone]);
    neighbours[keep] = std::move(merged);
    for (uint32_t c : neighbours[keep]) {
      const uint32_t a = std::min(keep, c), b = std::max(keep, c);
      heap.push({CvdMergeCost(sums[a], sums[b]), a, b, version[a], version[b]});
    }

    LevelMoves level;
    level.cluster_count = clusters;
    level.energy = energy.value();
    level.element = moved_faces;
    level.to_cluster = to_cluster;
    level.from_cluster = from_cluster;
    if (absl::Status s = sink.OnLevel(level); !s.ok()) return s;
    ++summary.levels;
    summary.moves += moved_faces.size();
  }
  summary.final_clusters = clusters;
  return summary;
}

}  // namespace mlclust
