// LN k-means inside the point levels (section 6.4.3, PML for data with LN k-means as
// minimizeEnergy): the one round driver of the CPU's PointSpace (point_clustering.cc) and
// the GPU's point levels (gpu/stages/points_optimise_gpu.h). Internal to core/cluster.
//
// After a level's merges, LN k-means around the merged clusters: round 0 checks their
// points and compares the points of the clusters next to them with the merged clusters
// that list their cluster; each later round, for up to `rounds` rounds, the points of the
// clusters the previous round changed. A point checked in this level keeps a margin (the
// assign stage's) and is checked again only once its own centroid's drift plus the largest
// drift of any centroid it can be compared with could have used it up (Hamerly's bound);
// with bounded_drift (ours) a cluster whose centroid moved by less than that share of its
// RMS radius keeps its unchecked points unchecked.
//
// The driver owns the member lists, the bounds and the apply pass; the caller's assign
// stage gets each round's slices of the member lists and returns the chosen moves in slice
// order (`Check` in Run), and sees each round's changes (`AfterRound`: the GPU writes them
// back).
#ifndef MLCLUST_CORE_CLUSTER_DETAIL_POINT_OPTIMISE_H_
#define MLCLUST_CORE_CLUSTER_DETAIL_POINT_OPTIMISE_H_

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "core/base/cancel.h"
#include "core/base/status_macros.h"
#include "core/cluster/detail/ln_kmeans_stages.h"
#include "core/cluster/detail/member_lists.h"
#include "core/hierarchy/level_recorder.h"

namespace mlclust::detail {

class PointOptimiseRounds {
 public:
  // A round's work: a slice of a cluster's member list [begin, end) (kSlicePoints members at
  // most). A region slice: its points to check (Scan). A slice of a cluster next to the
  // merged ones (round 0, compare_end > compare_begin): each point against its own centroid
  // and next_to's merged clusters [compare_begin, compare_end), the nearest strictly closer
  // one its target (not stamped).
  static constexpr size_t kSlicePoints = 256;
  // The ordered apply asks for the point this many moves ahead (each move waits on a few
  // of its point's entries; eight cover that wait, as the checks' look-ahead does).
  static constexpr size_t kApplyAhead = 8;
  struct Slice {
    uint32_t cluster;
    size_t begin, end;
    bool all;            // the cluster was in no round's region of this level yet
    bool unchecked_too;  // its points not checked in this level are checked
    uint32_t compare_begin = 0, compare_end = 0;
  };
  using NextTo = std::pair<uint32_t, uint32_t>;  // (cluster, merged cluster)
  using Move = std::pair<uint32_t, uint32_t>;    // (point, target cluster)

  // Member lists in point order within each cluster, from clusters' labels. `clusters` and
  // `recorder` must outlive the driver.
  PointOptimiseRounds(PointClusters& clusters, LevelRecorder& recorder, uint32_t rounds,
                      double bounded_drift)
      : clusters_(clusters), recorder_(recorder), rounds_(rounds), bounded_drift_(bounded_drift) {
    const uint32_t k = clusters.capacity();
    const size_t m = clusters.labels().size();
    members_.resize(k);
    position_.resize(m);
    for (size_t i = 0; i < m; ++i) {
      std::vector<uint32_t>& list = members_[clusters.label(i)];
      position_[i] = static_cast<uint32_t>(list.size());
      list.push_back(static_cast<uint32_t>(i));
    }
    mark_.assign(k, 0);
    stamp_.assign(m, 0);
    threshold_.assign(m, 0.0);
    drift_epoch_.assign(k, 0);
    drift_.assign(k, 0.0);
    region_epoch_.assign(k, 0);
  }

  std::span<const uint32_t> members(uint32_t c) const { return members_[c]; }

  // `gone`'s points into `keep` (the recorder told), the sums merged.
  void Merge(uint32_t keep, uint32_t gone) {
    Touch(keep);
    Touch(gone);
    for (uint32_t i : members_[gone]) {
      recorder_.RecordMove(i, gone);
      clusters_.SetLabel(i, keep);
      position_[i] = static_cast<uint32_t>(members_[keep].size());
      members_[keep].push_back(i);
    }
    std::vector<uint32_t>().swap(members_[gone]);
    clusters_.MergeSums(keep, gone);
  }

  // How far cluster c's centroid has moved in this level (a sum of steps).
  double Drift(uint32_t c) const { return drift_epoch_[c] == epoch_ ? drift_[c] : 0.0; }
  // The largest drift among the clusters a point of c can be compared with: c's
  // neighbours and theirs.
  double NeighbourhoodDrift(uint32_t c) const {
    double largest = 0;
    for (uint32_t n : clusters_.neighbours(c)) {
      if (n == kNoCluster) continue;
      largest = std::max(largest, Drift(n));
      for (uint32_t nn : clusters_.neighbours(n)) {
        if (nn != kNoCluster && nn != c) largest = std::max(largest, Drift(nn));
      }
    }
    return largest;
  }

  // A region slice's points to check into `out` (room for the slice), their count: `all`,
  // its members; otherwise, without branches (which of the two is unpredictable), the
  // unchecked ones and those over their threshold, the drift of its cluster and
  // neighbourhood (cached in `drift_of` for the cluster scanned last). Reads only.
  size_t Scan(const Slice& slice, uint32_t* out, std::pair<uint32_t, double>& drift_of) const {
    const uint32_t* list = members_[slice.cluster].data();
    if (slice.all) {
      std::copy(list + slice.begin, list + slice.end, out);
      return slice.end - slice.begin;
    }
    if (drift_of.first != slice.cluster) {
      drift_of = {slice.cluster, Drift(slice.cluster) + NeighbourhoodDrift(slice.cluster)};
    }
    const double drift = drift_of.second;
    const uint32_t* stamp = stamp_.data();
    const double* threshold = threshold_.data();
    const uint32_t epoch = epoch_;
    size_t count = 0;
    const auto unchecked_too = static_cast<size_t>(slice.unchecked_too);
    for (size_t at = slice.begin; at < slice.end; ++at) {
      const uint32_t i = list[at];
      out[count] = i;
      const auto unchecked = static_cast<size_t>(stamp[i] != epoch);
      const auto over = static_cast<size_t>(drift > threshold[i]);
      count += (unchecked & unchecked_too) | ((unchecked ^ 1) & over);
    }
    return count;
  }

  // A checked point: checked in this level, with the drift its margin can absorb. Slices
  // hold distinct points, so stages may stamp the points of different slices in parallel.
  void Stamp(uint32_t i, double margin) {
    stamp_[i] = epoch_;
    threshold_[i] = margin + Drift(clusters_.label(i));
  }

  // The level's rounds around the `merged` clusters (the neighbour lists those of before
  // the level's refresh). Per round
  //   absl::Status check(std::span<const Slice> slices, std::span<const NextTo> next_to,
  //                      std::vector<Move>& moves)
  // checks the slices' points (Scan; CheckPoint's target and margin, then Stamp) and
  // compares round 0's next-to slices, the moves in slice order into `moves` (cleared);
  // then the moves are applied in that order (a cluster's last point stays) and
  //   absl::Status after_round(std::span<const uint32_t> changed, std::span<const Move> moved)
  // sees the clusters that changed (centroids updated) and the moves made. Stops when a
  // round changes nothing, after `rounds` rounds, or once `cancel` is set (the caller
  // reports it); the stages' errors as they are.
  template <typename Check, typename AfterRound>
  absl::Status Run(std::span<const uint32_t> merged, const std::atomic<bool>* cancel, Check&& check,
                   AfterRound&& after_round) {
    std::vector<uint32_t> region;
    for (uint32_t c : merged) {
      if (!mark_[c] && clusters_.count(c) > 0) {
        mark_[c] = 1;
        region.push_back(c);
      }
    }
    std::vector<NextTo> next_to;
    for (uint32_t c : merged) {
      for (uint32_t n : clusters_.neighbours(c)) {
        if (n != kNoCluster && !mark_[n] && clusters_.count(n) > 0) next_to.push_back({n, c});
      }
    }
    for (uint32_t c : region) mark_[c] = 0;
    std::sort(next_to.begin(), next_to.end());
    next_to.erase(std::unique(next_to.begin(), next_to.end()), next_to.end());
    ++epoch_;
    std::vector<uint32_t> changed;
    std::vector<double> old_centroids;
    const uint32_t d = clusters_.dims();
    for (uint32_t round = 0; round < rounds_ && !region.empty() && !IsCancelled(cancel); ++round) {
      Select(region, /*first=*/round == 0, next_to);
      moves_.clear();
      MLCLUST_RETURN_IF_ERROR(
          check(std::span<const Slice>(slices_), std::span<const NextTo>(next_to), moves_));
      changed.clear();
      old_centroids.clear();
      made_.clear();
      // In order; the points of the moves ahead are asked for first (they lie anywhere).
      for (size_t n = 0; n < moves_.size(); ++n) {
        if (n + kApplyAhead < moves_.size()) Prefetch(moves_[n + kApplyAhead].first);
        ApplyMove(moves_[n].first, moves_[n].second, changed, old_centroids);
      }
      for (size_t n = 0; n < changed.size(); ++n) {
        const uint32_t c = changed[n];
        mark_[c] = 0;
        clusters_.UpdateCentroid(c);
        const std::span<const double> centroid = clusters_.centroid(c);
        double squared = 0;
        for (uint32_t j = 0; j < d; ++j) {
          const double diff = centroid[j] - old_centroids[n * d + j];
          squared += diff * diff;
        }
        drift_[c] += std::sqrt(squared) * (1 + 1e-12);
      }
      if (changed.empty()) break;
      MLCLUST_RETURN_IF_ERROR(
          after_round(std::span<const uint32_t>(changed), std::span<const Move>(made_)));
      region = changed;
    }
    return absl::OkStatus();
  }

 private:
  void Touch(uint32_t c) {
    recorder_.Touch(c, [&](uint32_t x) { return clusters_.Energy(x); });
  }

  // A round's slices, in region order: those not checked in this level, and those whose
  // centroid and neighbourhood moved by more than their threshold; a cluster no round of
  // this level has had in its region has no point checked yet: all of them. With
  // bounded_drift (ours), see the top. Round 0 (`first`): every point of the region, then
  // the points of the clusters in `next_to` (sorted (cluster, merged cluster) pairs).
  void Select(std::span<const uint32_t> region, bool first, std::span<const NextTo> next_to) {
    slices_.clear();
    for (uint32_t c : region) {
      bool all = true, unchecked_too = true;
      if (!first) {
        all = region_epoch_[c] != epoch_;
        if (bounded_drift_ > 0) {
          const double n = static_cast<double>(clusters_.count(c));
          const double radius = std::sqrt(std::max(0.0, clusters_.Energy(c)) / n);
          unchecked_too = Drift(c) >= bounded_drift_ * radius;
        }
        if (all && !unchecked_too) continue;
      }
      if (unchecked_too) region_epoch_[c] = epoch_;
      const size_t size = members_[c].size();
      for (size_t begin = 0; begin < size; begin += kSlicePoints) {
        slices_.push_back({c, begin, std::min(size, begin + kSlicePoints), all, unchecked_too});
      }
    }
    if (!first) return;
    for (size_t g = 0; g < next_to.size();) {
      size_t end = g;
      while (end < next_to.size() && next_to[end].first == next_to[g].first) ++end;
      const uint32_t c = next_to[g].first;
      const size_t size = members_[c].size();
      for (size_t begin = 0; begin < size; begin += kSlicePoints) {
        slices_.push_back({c, begin, std::min(size, begin + kSlicePoints), false, false,
                           static_cast<uint32_t>(g), static_cast<uint32_t>(end)});
      }
      g = end;
    }
  }

  // Asks the caches for what ApplyMove reads and writes of point i.
  void Prefetch(uint32_t i) const {
    clusters_.Prefetch(i);
    __builtin_prefetch(&position_[i]);
    __builtin_prefetch(&stamp_[i]);
  }

  // One chosen move, in the order of the checks (a cluster's last point stays): the sums,
  // the recorder, the member lists; a cluster that changes for the first time in this
  // round goes to `changed` with its old centroid.
  void ApplyMove(uint32_t i, uint32_t to, std::vector<uint32_t>& changed,
                 std::vector<double>& old_centroids) {
    const uint32_t from = clusters_.label(i);
    if (clusters_.count(from) <= 1) return;
    for (uint32_t c : {from, to}) {
      if (!mark_[c]) {
        mark_[c] = 1;
        changed.push_back(c);
        const std::span<const double> centroid = clusters_.centroid(c);
        old_centroids.insert(old_centroids.end(), centroid.begin(), centroid.end());
        if (drift_epoch_[c] != epoch_) {
          drift_epoch_[c] = epoch_;
          drift_[c] = 0;
        }
      }
    }
    Touch(from);
    Touch(to);
    recorder_.RecordMove(i, from);
    clusters_.Move(i, to);
    stamp_[i] = 0;  // its candidates are another cluster's now: check it again
    MoveMember(members_, position_, i, from, to);
    made_.push_back({i, to});
  }

  PointClusters& clusters_;
  LevelRecorder& recorder_;
  const uint32_t rounds_;
  const double bounded_drift_;
  std::vector<std::vector<uint32_t>> members_;
  std::vector<uint32_t> position_;
  std::vector<uint8_t> mark_;
  // Per point the level (epoch_) of its last check and the drift it can absorb; per
  // cluster its centroid's drift in the current level, and the last level that checked all
  // its points (one of that level's rounds had it in its region with its unchecked points).
  uint32_t epoch_ = 0;
  std::vector<uint32_t> stamp_, drift_epoch_, region_epoch_;
  std::vector<double> threshold_, drift_;
  std::vector<Slice> slices_;
  std::vector<Move> moves_, made_;
};

}  // namespace mlclust::detail

#endif  // MLCLUST_CORE_CLUSTER_DETAIL_POINT_OPTIMISE_H_
