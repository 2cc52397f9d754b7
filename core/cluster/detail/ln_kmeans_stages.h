// The state of LN k-means and of the point multilevel engine (clusters of points with
// their sums, centroids and local neighbours, section 6.1), and LN k-means' stages.
// Internal to core/cluster.
#ifndef MLCLUST_CORE_CLUSTER_DETAIL_LN_KMEANS_STAGES_H_
#define MLCLUST_CORE_CLUSTER_DETAIL_LN_KMEANS_STAGES_H_

#include <algorithm>
#include <cstdint>
#include <functional>
#include <limits>
#include <span>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"
#include "core/base/status_macros.h"
#include "core/cluster/detail/local_neighbours.h"
#include "core/cluster/detail/ode_heap.h"
#include "core/cluster/point_clustering.h"
#include "core/energy/variance_energy.h"
#include "core/points/points.h"
#include "tbb/blocked_range.h"
#include "tbb/parallel_for.h"

namespace mlclust::detail {

// Clusters of points with their sums, centroids and local neighbours. Coordinates are
// taken relative to the data's mean (`origin`) so that the energy from sums,
// sum |x|^2 - |sum x|^2 / n, keeps its precision.
class PointClusters {
 public:
  PointClusters(const PointSet& points, std::span<const uint32_t> labels, uint32_t capacity)
      : points_(points),
        d_(points.dims),
        labels_(labels.begin(), labels.end()),
        count_(capacity, 0),
        sum_(size_t{capacity} * d_, 0.0),
        square_(capacity, 0.0),
        centroid_(size_t{capacity} * d_, 0.0),
        neighbours_(size_t{capacity} * 2 * d_, kNoCluster),
        origin_(d_, 0.0),
        scratch_(capacity) {
    const size_t m = points.num_points();
    for (size_t i = 0; i < m; ++i) {
      for (uint32_t j = 0; j < d_; ++j) origin_[j] += points.values[i * d_ + j];
    }
    for (double& o : origin_) o /= static_cast<double>(std::max<size_t>(m, 1));
    for (size_t i = 0; i < m; ++i) Add(labels_[i], i, +1);
    for (uint32_t c = 0; c < capacity; ++c) UpdateCentroid(c);
  }

  uint32_t dims() const { return d_; }
  // Flat views for a device stage: the data's mean (d), every centroid (k x d, relative to
  // the mean) and every neighbour list (k x 2d, kNoCluster where none).
  std::span<const double> origin() const { return origin_; }
  std::span<const double> centroids() const { return centroid_; }
  std::span<const uint32_t> neighbour_table() const { return neighbours_; }
  std::span<uint32_t> neighbour_table() { return neighbours_; }
  uint32_t capacity() const { return static_cast<uint32_t>(count_.size()); }
  uint32_t label(size_t i) const { return labels_[i]; }
  std::span<const uint32_t> labels() const { return labels_; }
  uint64_t count(uint32_t c) const { return count_[c]; }
  std::span<const double> centroid(uint32_t c) const { return {&centroid_[size_t{c} * d_], d_}; }
  // Cluster c's coordinate sums (d) and square sum, relative to the origin.
  std::span<const double> sum(uint32_t c) const { return {&sum_[size_t{c} * d_], d_}; }
  double square(uint32_t c) const { return square_[c]; }
  std::span<uint32_t> neighbours(uint32_t c) { return {&neighbours_[size_t{c} * 2 * d_], 2 * d_}; }
  std::span<const uint32_t> neighbours(uint32_t c) const {
    return {&neighbours_[size_t{c} * 2 * d_], 2 * d_};
  }

  // Eq. 6.5 and its merge cost (core/energy/variance_energy.h) from the flat sums.
  double Energy(uint32_t c) const {
    return EnergyOfSums(static_cast<double>(count_[c]), {&sum_[size_t{c} * d_], d_}, square_[c]);
  }
  double MergeCost(uint32_t a, uint32_t b) const {
    return WardMergeCost(static_cast<double>(count_[a]), centroid(a),
                         static_cast<double>(count_[b]), centroid(b));
  }
  // |x_i - c|^2 with x_i relative to the origin.
  double Distance(size_t i, uint32_t c) const {
    const float* x = &points_.values[i * d_];
    const double* cc = &centroid_[size_t{c} * d_];
    double dist = 0;
    for (uint32_t j = 0; j < d_; ++j) {
      const double diff = (x[j] - origin_[j]) - cc[j];
      dist += diff * diff;
    }
    return dist;
  }
  // |x - c|^2 for x already relative to the origin (Relative).
  double DistanceTo(const double* x, uint32_t c) const {
    const double* cc = &centroid_[size_t{c} * d_];
    double dist = 0;
    for (uint32_t j = 0; j < d_; ++j) {
      const double diff = x[j] - cc[j];
      dist += diff * diff;
    }
    return dist;
  }
  // Asks the caches for point i's coordinates and label, which are read in random order.
  void Prefetch(size_t i) const {
    __builtin_prefetch(&points_.values[i * d_]);
    __builtin_prefetch(&labels_[i]);
  }
  void Relative(size_t i, std::vector<double>& out) const {
    out.resize(d_);
    for (uint32_t j = 0; j < d_; ++j) out[j] = points_.values[i * d_ + j] - origin_[j];
  }

  void Move(size_t i, uint32_t to) {
    Add(labels_[i], i, -1);
    labels_[i] = to;
    Add(to, i, +1);
  }
  // All of `gone`'s sums into `keep` (labels are the caller's, via SetLabel).
  void MergeSums(uint32_t keep, uint32_t gone) {
    count_[keep] += count_[gone];
    square_[keep] += square_[gone];
    for (uint32_t j = 0; j < d_; ++j) sum_[size_t{keep} * d_ + j] += sum_[size_t{gone} * d_ + j];
    count_[gone] = 0;
    square_[gone] = 0;
    std::fill(&sum_[size_t{gone} * d_], &sum_[size_t{gone} * d_] + d_, 0.0);
    UpdateCentroid(keep);
  }
  void SetLabel(size_t i, uint32_t c) { labels_[i] = c; }
  void UpdateCentroid(uint32_t c) {
    const double n = static_cast<double>(count_[c]);
    for (uint32_t j = 0; j < d_; ++j) {
      centroid_[size_t{c} * d_ + j] = n > 0 ? sum_[size_t{c} * d_ + j] / n : 0.0;
    }
  }

  // Eq. 6.1 neighbours of `c` from `candidates` (its own and the second-order ones, or
  // any others the caller adds): the nearest candidate centroid in each subspace
  // (RefreshLocalNeighbours, local_neighbours.h).
  void RefreshNeighbours(uint32_t c, std::vector<uint32_t>& candidates) {
    RefreshLocalNeighbours<uint64_t>(c, d_, centroid_, count_, neighbours_, candidates, scratch_);
  }

  double TotalEnergy() const {
    double total = 0;
    for (uint32_t c = 0; c < capacity(); ++c) total += Energy(c);
    return total;
  }

 private:
  void Add(uint32_t c, size_t i, int sign) {
    const float* x = &points_.values[i * d_];
    double s2 = 0;
    for (uint32_t j = 0; j < d_; ++j) {
      const double v = x[j] - origin_[j];
      sum_[size_t{c} * d_ + j] += sign * v;
      s2 += v * v;
    }
    square_[c] += sign * s2;
    count_[c] += sign;
  }

  const PointSet& points_;
  const uint32_t d_;
  std::vector<uint32_t> labels_;
  std::vector<uint64_t> count_;
  std::vector<double> sum_;
  std::vector<double> square_;
  std::vector<double> centroid_;
  std::vector<uint32_t> neighbours_;
  std::vector<double> origin_;
  LocalNeighbourScratch scratch_;  // RefreshNeighbours'
};

// LN k-means (Alg. 6.1) in three stages, each replaceable on its own (a device backend
// can take one and leave the others): assign (ChooseTargets) -> apply (ApplyMoves) ->
// refresh the neighbours (RefreshAround). The CPU versions are in point_clustering.cc.

// Stage 1, assign: for each of `points_to_check` (indices), the best cluster among its
// own, its cluster's neighbours and the neighbours of the neighbour in its subspace; writes
// the target (kNoCluster: stays). With `margin`, also how far the point is from changing
// its mind: for a point that stays, the distance to its second-best candidate minus the
// distance to its own centroid; -infinity for a point that moves. Reads `clusters` only;
// points in parallel.
void ChooseTargets(const PointClusters& clusters, std::span<const uint32_t> points_to_check,
                   std::span<uint32_t> target, std::span<double> margin = {});

// Stage 2, apply: the chosen moves in order (a cluster's last point stays), with
// on_move(point, from, to) after each; returns the clusters that changed, whose centroids
// it updates. `mark` (one byte per cluster, all 0) is scratch, left all 0; `moved` counts.
std::vector<uint32_t> ApplyMoves(PointClusters& clusters, std::span<const uint32_t> points,
                                 std::span<const uint32_t> target, std::vector<uint8_t>& mark,
                                 uint64_t& moved,
                                 const std::function<void(uint32_t, uint32_t, uint32_t)>& on_move);

// Stage 3, refresh: the local neighbours (eq. 6.1) of the `changed` clusters and of their
// neighbours, from their second-order neighbours; returns the refreshed clusters. `mark`
// as for ApplyMoves.
std::vector<uint32_t> RefreshAround(PointClusters& clusters, std::span<const uint32_t> changed,
                                    std::vector<uint8_t>& mark);

// The points whose cluster is active, in index order, into `check`: slices of the points
// in parallel, joined in order (the same list as a plain loop, on any number of threads).
inline void CollectActive(std::span<const uint32_t> labels, const std::vector<uint8_t>& active,
                          std::vector<uint32_t>& check) {
  constexpr size_t kSlice = 65536;
  const size_t m = labels.size();
  const size_t slices = (m + kSlice - 1) / kSlice;
  std::vector<size_t> counts(slices, 0);
  check.resize(m);
  // Each slice compacts into its own part of `check`, then the parts move down in order.
  tbb::parallel_for(tbb::blocked_range<size_t>(0, slices, 1), [&](const auto& range) {
    for (size_t s = range.begin(); s != range.end(); ++s) {
      const size_t begin = s * kSlice, end = std::min(m, begin + kSlice);
      size_t count = 0;
      for (size_t i = begin; i < end; ++i) {
        check[begin + count] = static_cast<uint32_t>(i);
        count += active[labels[i]];
      }
      counts[s] = count;
    }
  });
  size_t at = 0;
  for (size_t s = 0; s < slices; ++s) {
    const size_t begin = s * kSlice;
    if (at != begin) std::copy_n(check.begin() + begin, counts[s], check.begin() + at);
    at += counts[s];
  }
  check.resize(at);
}

// Alg. 6.1's iterations on clusters whose neighbours are set, with the assign stage
// `assign` (the shape of ChooseTargets without a margin):
//   absl::Status assign(const PointClusters&, std::span<const uint32_t> points_to_check,
//                       std::span<uint32_t> target)
// then ApplyMoves and RefreshAround; after the first iteration a point is checked again
// only if its cluster, a neighbour of it or a neighbour's neighbour changed (its centroid
// or its neighbour list). Fills result's energies, iterations, moves and converged (not
// labels). CANCELLED once options.cancel is set (checked after each stage); the assign
// stage's errors as they are. The CPU (point_clustering.cc, ChooseTargets in slices) and
// the device backends (gpu/stages/point_stages_gpu.h) run it.
template <typename Assign>
absl::Status RunLnKmeansIterations(PointClusters& clusters, const LnKmeansOptions& options,
                                   LnKmeansResult& result, Assign&& assign) {
  const size_t m = clusters.labels().size();
  const uint32_t k = clusters.capacity();
  auto cancelled = [&](uint32_t iteration) {
    if (!IsCancelled(options.cancel)) return absl::OkStatus();
    return CheckCancelled(options.cancel, absl::StrCat("LN k-means iteration ", iteration));
  };
  result.initial_energy = clusters.TotalEnergy();
  std::vector<uint32_t> check(m), target(m);
  for (size_t i = 0; i < m; ++i) check[i] = static_cast<uint32_t>(i);
  std::vector<uint8_t> mark(k, 0), dirty(k, 0), active(k, 0);
  for (uint32_t iteration = 1; iteration <= options.max_iterations; ++iteration) {
    MLCLUST_RETURN_IF_ERROR(cancelled(iteration));
    target.resize(check.size());
    MLCLUST_RETURN_IF_ERROR(assign(static_cast<const PointClusters&>(clusters),
                                   std::span<const uint32_t>(check), std::span<uint32_t>(target)));
    MLCLUST_RETURN_IF_ERROR(cancelled(iteration));
    uint64_t moved = 0;
    const std::vector<uint32_t> changed = ApplyMoves(clusters, check, target, mark, moved, {});
    result.iterations = iteration;
    result.moves += moved;
    if (options.on_iteration) options.on_iteration(iteration, moved, clusters.TotalEnergy());
    if (moved == 0) {
      result.converged = true;
      break;
    }
    const std::vector<uint32_t> refreshed = RefreshAround(clusters, changed, mark);
    MLCLUST_RETURN_IF_ERROR(cancelled(iteration));
    std::fill(dirty.begin(), dirty.end(), 0);
    for (uint32_t c : changed) dirty[c] = 1;
    for (uint32_t c : refreshed) dirty[c] = 1;
    for (uint32_t c = 0; c < k; ++c) {
      bool any = dirty[c];
      for (uint32_t n : clusters.neighbours(c)) {
        if (any || n == kNoCluster) continue;
        any = dirty[n];
        for (uint32_t nn : clusters.neighbours(n)) {
          if (nn != kNoCluster && dirty[nn]) any = true;
        }
      }
      active[c] = any;
    }
    CollectActive(clusters.labels(), active, check);
  }
  result.energy = clusters.TotalEnergy();
  return absl::OkStatus();
}

}  // namespace mlclust::detail

#endif  // MLCLUST_CORE_CLUSTER_DETAIL_LN_KMEANS_STAGES_H_
