#include "core/cluster/bisecting_kmeans.h"

#include <cmath>
#include <queue>
#include <utility>

#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"
#include "core/base/random.h"
#include "core/base/status_macros.h"
#include "core/cluster/detail/subset_sum_of_squares.h"

namespace mlclust {
namespace {

// Below this many points a 2-means run stays on the calling thread: spreading a small
// cluster over a pool costs more than it saves.
constexpr size_t kParallelPoints = 65536;

struct Cluster {
  std::vector<uint32_t> members;
  double sse = 0;
};

// Priority of a cluster for the next split: larger key first, ties to the smaller id.
struct Candidate {
  double key = 0;
  uint32_t id = 0;
  bool operator<(const Candidate& other) const {
    if (key != other.key) return key < other.key;
    return id > other.id;
  }
};

absl::Status CheckOptions(const PointSet& points, const BisectingKmeansOptions& options) {
  MLCLUST_RETURN_IF_ERROR(ValidatePoints(points));
  const size_t m = points.num_points();
  if (options.clusters < 1 || options.clusters > m) {
    return absl::InvalidArgumentError(absl::StrCat(
        "'clusters' must be in [1, ", m, "] (the number of points), not ", options.clusters));
  }
  if (options.trials < 1) return absl::InvalidArgumentError("'trials' must be at least 1");
  return detail::CheckInnerKmeansOptions(options);
}

}  // namespace

absl::StatusOr<BisectingKmeansResult> RunBisectingKmeans(const PointSet& points,
                                                         const BisectingKmeansOptions& options) {
  MLCLUST_RETURN_IF_ERROR(CheckOptions(points, options));
  const size_t m = points.num_points();
  const uint32_t d = points.dims;
  const uint32_t k = options.clusters;
  const bool by_size = options.split == BisectingKmeansOptions::SplitChoice::kLargestSize;

  BisectingKmeansResult result;
  std::vector<Cluster> clusters(1);
  clusters.reserve(k);
  clusters[0].members.resize(m);
  for (size_t i = 0; i < m; ++i) clusters[0].members[i] = static_cast<uint32_t>(i);
  clusters[0].sse = detail::SubsetSumOfSquares(points, clusters[0].members);
  result.initial_energy = clusters[0].sse;
  double total = clusters[0].sse;

  auto key_of = [&](const Cluster& c) {
    return by_size ? static_cast<double>(c.members.size()) : c.sse;
  };
  std::priority_queue<Candidate> queue;
  queue.push({key_of(clusters[0]), 0});
  Random seeds(options.seed);

  while (clusters.size() < k) {
    MLCLUST_RETURN_IF_ERROR(
        CheckCancelled(options.cancel, absl::StrCat("bisecting k-means split ", clusters.size())));
    // Alg. 2.7 line 3: pick a cluster to split. One of one point cannot be split; since
    // k <= m, a cluster of two or more points is left while fewer than k clusters exist.
    const uint32_t parent = queue.top().id;
    queue.pop();
    Cluster& split = clusters[parent];
    if (split.members.size() < 2) continue;

    // Line 4, the bisecting step: 2-means `trials` times, the split of least energy kept.
    const PointSet subset = detail::Subset(points, split.members);
    KmeansOptions two_means = KmeansOptionsFor(options, 2);
    two_means.threads = split.members.size() >= kParallelPoints ? options.threads : 1;
    std::vector<ClusterId> best_labels;
    double best_inertia = 0;
    for (uint32_t trial = 0; trial < options.trials; ++trial) {
      two_means.seed = seeds.Next();
      MLCLUST_ASSIGN_OR_RETURN(KmeansResult run, RunKmeans(subset, two_means));
      if (trial == 0 || run.inertia < best_inertia) {
        best_inertia = run.inertia;
        best_labels = std::move(run.labels);
      }
    }

    Cluster first, second;
    for (size_t n = 0; n < best_labels.size(); ++n) {
      (best_labels[n].value() == 0 ? first : second).members.push_back(split.members[n]);
    }
    first.sse = detail::SubsetSumOfSquares(points, first.members);
    second.sse = detail::SubsetSumOfSquares(points, second.members);
    total += first.sse + second.sse - split.sse;
    const uint32_t child = static_cast<uint32_t>(clusters.size());
    result.splits.push_back(
        {ClusterId(parent), ClusterId(child), total, first.members.size(), second.members.size()});
    clusters[parent] = std::move(first);
    clusters.push_back(std::move(second));
    queue.push({key_of(clusters[parent]), parent});
    queue.push({key_of(clusters[child]), child});
  }

  result.labels.assign(m, ClusterId(0));
  result.centres.assign(size_t{k} * d, 0.0f);
  result.inertia = 0;
  std::vector<double> mean;
  for (uint32_t c = 0; c < clusters.size(); ++c) {
    result.inertia += detail::SubsetSumOfSquares(points, clusters[c].members, &mean);
    for (uint32_t j = 0; j < d; ++j)
      result.centres[size_t{c} * d + j] = static_cast<float>(mean[j]);
    for (uint32_t i : clusters[c].members) result.labels[i] = ClusterId(c);
  }
  return result;
}

absl::Status EmitBisectingLevels(const BisectingKmeansResult& result, LevelSink& sink) {
  const uint32_t k = static_cast<uint32_t>(result.splits.size()) + 1;
  // The points of each cluster as the splits are undone: undoing split j moves the points
  // now in its child (its final points and those of every later split of it, already
  // undone) back to its parent.
  std::vector<std::vector<uint32_t>> members(k);
  for (size_t i = 0; i < result.labels.size(); ++i) {
    const uint32_t c = result.labels[i].value();
    if (c >= k) {
      return absl::InvalidArgumentError(
          absl::StrCat("point ", i, " has cluster ", c, " but the result has ", k, " clusters"));
    }
    members[c].push_back(static_cast<uint32_t>(i));
  }
  for (size_t j = 0; j < result.splits.size(); ++j) {
    const uint32_t parent = result.splits[j].parent.value(), child = result.splits[j].child.value();
    if (child != j + 1 || parent >= child) {
      return absl::InvalidArgumentError(absl::StrCat("split ", j, " makes cluster ", child,
                                                     " from ", parent, "; expected cluster ", j + 1,
                                                     " from a smaller id"));
    }
  }
  MLCLUST_RETURN_IF_ERROR(sink.OnStart(result.labels, k, result.inertia));
  std::vector<uint32_t> to, from;
  for (size_t j = result.splits.size(); j-- > 0;) {
    const BisectingSplit& split = result.splits[j];
    const uint32_t parent = split.parent.value(), child = split.child.value();
    std::vector<uint32_t>& moved = members[child];
    to.assign(moved.size(), parent);
    from.assign(moved.size(), child);
    LevelMoves level;
    level.level = static_cast<uint32_t>(result.splits.size() - j);
    level.cluster_count = static_cast<uint32_t>(j) + 1;
    level.energy = j == 0 ? result.initial_energy : result.splits[j - 1].energy;
    level.element = moved;
    level.to_cluster = to;
    level.from_cluster = from;
    MLCLUST_RETURN_IF_ERROR(sink.OnLevel(level));
    members[parent].insert(members[parent].end(), moved.begin(), moved.end());
    moved = {};
  }
  return absl::OkStatus();
}

}  // namespace mlclust
