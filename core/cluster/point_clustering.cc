#include "core/cluster/point_clustering.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <memory>
#include <numeric>

#include "absl/container/flat_hash_map.h"
#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"
#include "core/base/random.h"
#include "core/base/status_macros.h"
#include "core/cluster/detail/ln_kmeans_stages.h"
#include "core/cluster/detail/multilevel_engine.h"
#include "core/cluster/detail/point_levels_checks.h"
#include "core/cluster/detail/point_optimise.h"
#include "core/cluster/kmeans.h"
#include "core/energy/variance_energy.h"
#include "core/hierarchy/level_recorder.h"
#include "tbb/parallel_for.h"
#include "tbb/task_arena.h"

namespace mlclust {
namespace detail {
namespace {
constexpr uint32_t kNone = kNoCluster;
}  // namespace

// One point's LN k-means check: its best cluster among its own, its cluster's neighbours
// and the neighbours of the neighbour in its subspace. Returns the target (kNone: stays)
// and, with kMargin, sets `margin`: for a point that stays, the distance to its second-
// best candidate minus the distance to its own centroid (so it stays while its own
// centroid and the candidates move by less than that in all); -infinity for a point that
// moves. `x` is scratch. Reads `clusters` only (safe in parallel).
template <bool kMargin>
[[gnu::always_inline]] inline uint32_t CheckPoint(const PointClusters& clusters, uint32_t i,
                                                  std::vector<double>& x, double& margin) {
  uint32_t candidates[256];
  const uint32_t own = clusters.label(i);
  clusters.Relative(i, x);
  const uint32_t s = SubspaceIndex(clusters.centroid(own), x);
  int count = 0;
  for (uint32_t n : clusters.neighbours(own)) {
    if (n != kNone && count < 256) candidates[count++] = n;
  }
  const uint32_t towards = clusters.neighbours(own)[s];
  if (towards != kNone) {
    for (uint32_t n : clusters.neighbours(towards)) {
      if (n != kNone && n != own && count < 256) candidates[count++] = n;
    }
  }
  const double own_distance = clusters.DistanceTo(x.data(), own);
  double best = own_distance;
  double second = std::numeric_limits<double>::infinity();
  uint32_t best_cluster = own;
  for (int c = 0; c < count; ++c) {
    const uint32_t n = candidates[c];
    if (n == best_cluster || clusters.count(n) == 0) continue;
    const double dist = clusters.DistanceTo(x.data(), n);
    if (dist < best || (dist == best && n < best_cluster && n != own)) {
      second = best;
      best = dist;
      best_cluster = n;
    } else if (dist < second) {
      second = dist;
    }
  }
  if constexpr (kMargin) {
    margin = best_cluster != own ? -std::numeric_limits<double>::infinity()
                                 : std::sqrt(second) - std::sqrt(own_distance);
  }
  return best_cluster != own ? best_cluster : kNone;
}

// One LN k-means pass over `points_to_check` (indices): CheckPoint for each, in parallel.
// Writes the point's target (kNone: stays) and, with `margin`, its margin.
void ChooseTargets(const PointClusters& clusters, std::span<const uint32_t> points_to_check,
                   std::span<uint32_t> target, std::span<double> margin) {
  tbb::parallel_for(
      tbb::blocked_range<size_t>(0, points_to_check.size(), 1024), [&](const auto& range) {
        std::vector<double> x;
        double point_margin = 0;
        for (size_t r = range.begin(); r != range.end(); ++r) {
          if (r + 8 < range.end()) clusters.Prefetch(points_to_check[r + 8]);
          if (margin.empty()) {
            target[r] = CheckPoint<false>(clusters, points_to_check[r], x, point_margin);
          } else {
            target[r] = CheckPoint<true>(clusters, points_to_check[r], x, point_margin);
            margin[r] = point_margin;
          }
        }
      });
}

// Applies the chosen moves (a cluster's last point stays) and returns the clusters that
// changed. Centroids of changed clusters are updated.
std::vector<uint32_t> ApplyMoves(PointClusters& clusters, std::span<const uint32_t> points,
                                 std::span<const uint32_t> target, std::vector<uint8_t>& mark,
                                 uint64_t& moved,
                                 const std::function<void(uint32_t, uint32_t, uint32_t)>& on_move) {
  std::vector<uint32_t> changed;
  for (size_t r = 0; r < points.size(); ++r) {
    if (target[r] == kNone) continue;
    const uint32_t i = points[r];
    const uint32_t from = clusters.label(i);
    if (clusters.count(from) <= 1) continue;
    clusters.Move(i, target[r]);
    ++moved;
    if (on_move) on_move(i, from, target[r]);
    for (uint32_t c : {from, target[r]}) {
      if (!mark[c]) {
        mark[c] = 1;
        changed.push_back(c);
      }
    }
  }
  for (uint32_t c : changed) {
    mark[c] = 0;
    clusters.UpdateCentroid(c);
  }
  return changed;
}

// Refreshes the neighbours of the changed clusters and of their neighbours.
std::vector<uint32_t> RefreshAround(PointClusters& clusters, std::span<const uint32_t> changed,
                                    std::vector<uint8_t>& mark) {
  std::vector<uint32_t> affected;
  for (uint32_t c : changed) {
    if (!mark[c]) {
      mark[c] = 1;
      affected.push_back(c);
    }
    for (uint32_t n : clusters.neighbours(c)) {
      if (n != kNone && !mark[n]) {
        mark[n] = 1;
        affected.push_back(n);
      }
    }
  }
  // Each refresh looks at the cluster's neighbours and their neighbours (second order),
  // which is where a changed cluster next to it can be.
  std::vector<uint32_t> candidates;
  for (uint32_t c : affected) {
    mark[c] = 0;
    if (clusters.count(c) > 0) clusters.RefreshNeighbours(c, candidates);
  }
  return affected;
}

}  // namespace detail

namespace {

using detail::ChooseTargets;
using detail::PointClusters;

constexpr uint32_t kNone = detail::kNoCluster;
// LN k-means' assignment runs over this many points at a time between cancellation checks.
constexpr size_t kAssignSlice = 65536;

// First neighbours of a seeded start: brute force over all pairs of clusters, in parallel
// (O(k^2 d); voxel starts use VoxelNeighbours instead). Once `cancel` is set the blocks
// not yet started are skipped (the caller checks it).
void InitialNeighbours(PointClusters& clusters, const std::atomic<bool>* cancel) {
  const uint32_t k = clusters.capacity();
  const uint32_t d = clusters.dims();
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, k, 16), [&](const auto& range) {
    if (IsCancelled(cancel)) return;
    std::vector<double> best_local(2 * d);
    for (uint32_t c = range.begin(); c != range.end(); ++c) {
      std::span<uint32_t> out = clusters.neighbours(c);
      std::fill(out.begin(), out.end(), kNone);
      if (clusters.count(c) == 0) continue;
      std::fill(best_local.begin(), best_local.end(), std::numeric_limits<double>::infinity());
      for (uint32_t n = 0; n < k; ++n) {
        if (n == c || clusters.count(n) == 0) continue;
        const uint32_t s = SubspaceIndex(clusters.centroid(c), clusters.centroid(n));
        double dist = 0;
        for (uint32_t j = 0; j < d; ++j) {
          const double diff = clusters.centroid(c)[j] - clusters.centroid(n)[j];
          dist += diff * diff;
        }
        if (dist < best_local[s]) {
          best_local[s] = dist;
          out[s] = n;
        }
      }
    }
  });
}

// Occupied voxel cells: per point its cell's cluster, per cluster its cell coordinates.
struct VoxelCells {
  std::vector<uint32_t> labels;
  std::vector<std::vector<uint32_t>> cell;  // per cluster
};

// The bounding box of the points, per axis.
struct Bounds {
  std::vector<float> lo, hi;
};
Bounds BoundsOf(const PointSet& points) {
  const uint32_t d = points.dims;
  Bounds bounds{std::vector<float>(d, std::numeric_limits<float>::max()),
                std::vector<float>(d, -std::numeric_limits<float>::max())};
  for (size_t i = 0; i < points.num_points(); ++i) {
    for (uint32_t j = 0; j < d; ++j) {
      bounds.lo[j] = std::min(bounds.lo[j], points.values[i * d + j]);
      bounds.hi[j] = std::max(bounds.hi[j], points.values[i * d + j]);
    }
  }
  return bounds;
}

// The occupied cells of the bounding box cut into cells_per_axis[j] cells along axis j,
// numbered in order of their first point. Once `cancel` is set it stops early with no cells
// (the caller checks it). Where the cell coordinates pack into 64 bits (3-D: up to 2^21
// cells per axis), each point's packed cell is found in parallel blocks and the numbering
// runs over the packed keys (a flat hash of integers, no key allocated per point): the same
// cells and labels as the general path, which stays for keys that do not fit (more
// dimensions). About 0.1 s of the start's ordered work at 1M 3-D points; the keys hold 8
// bytes per point while the start runs.
VoxelCells OccupiedCells(const PointSet& points, const Bounds& bounds,
                         std::span<const uint32_t> cells_per_axis,
                         const std::atomic<bool>* cancel) {
  const uint32_t d = points.dims;
  const size_t m = points.num_points();
  auto cell_of = [&](size_t i, uint32_t j) {
    const uint32_t a = cells_per_axis[j];
    const double span = static_cast<double>(bounds.hi[j]) - bounds.lo[j];
    const double t = span > 0 ? (points.values[i * d + j] - bounds.lo[j]) / span : 0.0;
    // Clamped in double: an axis spanning more than float's range makes the float offset
    // above infinite, and casting infinity to uint32 is undefined (found by fuzzing).
    return static_cast<uint32_t>(std::min<double>(a - 1, t * a));
  };
  VoxelCells cells;
  std::vector<uint32_t> bits(d);
  uint32_t total_bits = 0;
  for (uint32_t j = 0; j < d; ++j) {
    bits[j] = static_cast<uint32_t>(std::bit_width(std::max(cells_per_axis[j], 1u) - 1));
    total_bits += bits[j];
  }
  if (total_bits <= 64) {
    constexpr size_t kBlock = 65536;
    std::vector<uint64_t> keys(m);
    std::atomic<bool> stopped{false};
    tbb::parallel_for(tbb::blocked_range<size_t>(0, m, kBlock), [&](const auto& range) {
      if (IsCancelled(cancel)) {
        stopped = true;
        return;
      }
      for (size_t i = range.begin(); i != range.end(); ++i) {
        uint64_t key = 0;
        for (uint32_t j = 0; j < d; ++j) key = (key << bits[j]) | cell_of(i, j);
        keys[i] = key;
      }
    });
    if (stopped) return VoxelCells();
    absl::flat_hash_map<uint64_t, uint32_t> index;
    cells.labels.resize(m);
    for (size_t i = 0; i < m; ++i) {
      auto [it, inserted] = index.try_emplace(keys[i], static_cast<uint32_t>(cells.cell.size()));
      if (inserted) {
        std::vector<uint32_t> cell(d);
        uint64_t key = keys[i];
        for (uint32_t j = d; j-- > 0;) {
          cell[j] = static_cast<uint32_t>(key & ((uint64_t{1} << bits[j]) - 1));
          key >>= bits[j];
        }
        cells.cell.push_back(std::move(cell));
      }
      cells.labels[i] = it->second;
    }
    return cells;
  }
  absl::flat_hash_map<std::vector<uint32_t>, uint32_t, absl::Hash<std::vector<uint32_t>>> index;
  cells.labels.resize(m);
  std::vector<uint32_t> cell(d);
  for (size_t i = 0; i < m; ++i) {
    if (i % 65536 == 0 && IsCancelled(cancel)) return VoxelCells();
    for (uint32_t j = 0; j < d; ++j) cell[j] = cell_of(i, j);
    auto [it, inserted] = index.try_emplace(cell, static_cast<uint32_t>(cells.cell.size()));
    if (inserted) cells.cell.push_back(cell);
    cells.labels[i] = it->second;
  }
  return cells;
}

// The cells per axis of the start (VoxelStartCells), occupied cells counted in one sweep.
std::vector<uint32_t> StartCells(const PointSet& points, const Bounds& bounds, uint32_t grid,
                                 const std::atomic<bool>* cancel) {
  absl::StatusOr<std::vector<uint32_t>> cells = VoxelStartCells(
      points.num_points(), bounds.lo, bounds.hi, grid, cancel,
      [&](std::span<const uint32_t> counts) -> absl::StatusOr<uint32_t> {
        const std::vector<uint32_t> trial(counts.begin(), counts.end());
        return static_cast<uint32_t>(OccupiedCells(points, bounds, trial, cancel).cell.size());
      });
  return *std::move(cells);  // this count never fails
}

// First neighbours of a voxel start: the face-sharing occupied cells, then the refresh
// picks the nearest per subspace from them and their neighbours. Once `cancel` is set it
// stops early (the caller checks it).
void VoxelNeighbours(const VoxelCells& cells, PointClusters& clusters,
                     const std::atomic<bool>* cancel) {
  const uint32_t k = static_cast<uint32_t>(cells.cell.size());
  const uint32_t d = clusters.dims();
  absl::flat_hash_map<std::vector<uint32_t>, uint32_t, absl::Hash<std::vector<uint32_t>>> index;
  for (uint32_t c = 0; c < k; ++c) index[cells.cell[c]] = c;
  std::vector<uint32_t> probe(d);
  for (uint32_t c = 0; c < k; ++c) {
    std::span<uint32_t> out = clusters.neighbours(c);
    for (uint32_t j = 0; j < d; ++j) {
      for (int side = 0; side < 2; ++side) {
        probe = cells.cell[c];
        if (side == 0) {
          ++probe[j];
        } else {
          if (probe[j] == 0) continue;
          --probe[j];
        }
        auto it = index.find(probe);
        if (it != index.end()) out[2 * j + side] = it->second;
      }
    }
  }
  std::vector<uint32_t> candidates;
  for (uint32_t c = 0; c < k; ++c) {
    if (c % 4096 == 0 && IsCancelled(cancel)) return;
    clusters.RefreshNeighbours(c, candidates);
  }
}

absl::Status CheckLnKmeansCancelled(const std::atomic<bool>* cancel, uint32_t iteration) {
  if (!IsCancelled(cancel)) return absl::OkStatus();
  return CheckCancelled(cancel, absl::StrCat("LN k-means iteration ", iteration));
}

// Alg. 6.1's iterations on clusters whose neighbours are set; fills result's energies,
// iterations, moves and converged (not labels). CANCELLED once options.cancel is set.
absl::Status LnKmeansIterations(PointClusters& clusters, const LnKmeansOptions& options,
                                LnKmeansResult& result) {
  // The staged loop (detail/ln_kmeans_stages.h) with the CPU's assign stage, in slices so
  // that a cancel is seen within one slice of a large set.
  uint32_t iteration = 0;
  return detail::RunLnKmeansIterations(
      clusters, options, result,
      [&](const PointClusters& current, std::span<const uint32_t> check,
          std::span<uint32_t> target) -> absl::Status {
        ++iteration;
        for (size_t begin = 0; begin < check.size(); begin += kAssignSlice) {
          const size_t count = std::min(kAssignSlice, check.size() - begin);
          ChooseTargets(current, check.subspan(begin, count), target.subspan(begin, count));
          MLCLUST_RETURN_IF_ERROR(CheckLnKmeansCancelled(options.cancel, iteration));
        }
        return absl::OkStatus();
      });
}

// The points' space for the multilevel engine (detail/multilevel_engine.h): clusters of
// points from the voxel start, the local neighbours (and who lists whom) in place of face
// adjacency, LN k-means in place of EMLO.
class PointSpace {
 public:
  using Engine = detail::MultilevelEngine<PointSpace>;
  static constexpr bool kOptimiseAllAtHandover = false;
  using Slice = detail::PointOptimiseRounds::Slice;
  using NextTo = detail::PointOptimiseRounds::NextTo;
  using Move = detail::PointOptimiseRounds::Move;

  // `cells`: the voxel start (OccupiedCells), complete. The set-up stops early once
  // options.cancel is set; ReportStart then returns CANCELLED.
  PointSpace(const PointSet& points, const PointMultilevelOptions& options, const VoxelCells& cells)
      : points_(points), options_(options), d_(points.dims) {
    k0_ = static_cast<uint32_t>(cells.cell.size());
    // The engine works on a copy of the points ordered by starting cell, so that a
    // cluster's points lie together in memory (clusters grow by merging, so they stay in a
    // few runs); original_ maps back to the caller's indices.
    const size_t m = points.num_points();
    std::vector<uint32_t> first(k0_ + 1, 0);
    for (uint32_t c : cells.labels) ++first[c + 1];
    std::partial_sum(first.begin(), first.end(), first.begin());
    original_.resize(m);
    std::vector<uint32_t> sorted_labels(m);
    for (size_t i = 0; i < m; ++i) {
      const uint32_t at = first[cells.labels[i]]++;
      original_[at] = static_cast<uint32_t>(i);
      sorted_labels[at] = cells.labels[i];
    }
    sorted_.dims = d_;
    sorted_.values.resize(points.values.size());
    for (size_t at = 0; at < m; ++at) {
      std::copy_n(&points.values[size_t{original_[at]} * d_], d_, &sorted_.values[at * d_]);
    }
    clusters_ = std::make_unique<PointClusters>(sorted_, sorted_labels, k0_);
    VoxelNeighbours(cells, *clusters_, options.cancel);
    reverse_.resize(k0_);
    for (uint32_t c = 0; c < k0_; ++c) {
      for (uint32_t n : clusters_->neighbours(c)) {
        if (n != kNone) reverse_[n].push_back(c);
      }
    }
    for (uint32_t c = 0; c < k0_ && !IsCancelled(options.cancel); ++c) {
      std::span<const uint32_t> out = clusters_->neighbours(c);
      if (std::all_of(out.begin(), out.end(), [](uint32_t n) { return n == kNone; })) {
        LinkIsolated(c);
      }
    }
    recorder_ = LevelRecorder(points.num_points(), k0_);
    mark_.assign(k0_, 0);
    into_.assign(k0_, kNone);
    partner_.assign(k0_, kNone);
    optimise_ = std::make_unique<detail::PointOptimiseRounds>(
        *clusters_, recorder_, options.optimise_rounds, options.bounded_drift);
  }

  uint32_t capacity() const { return k0_; }
  uint32_t start_clusters() const { return k0_; }

  // Level 0: the voxel clusters.
  absl::Status ReportStart(LevelSink& sink) {
    MLCLUST_RETURN_IF_ERROR(CheckCancelled(options_.cancel, "the voxel start"));
    std::vector<ClusterId> start(points_.num_points());
    for (size_t i = 0; i < start.size(); ++i) start[original_[i]] = ClusterId(clusters_->label(i));
    recorder_.Reset(clusters_->TotalEnergy());
    return sink.OnStart(start, k0_, recorder_.energy());
  }

  bool Alive(uint32_t c) const { return clusters_->count(c) > 0; }
  uint32_t Size(uint32_t c) const { return clusters_->count(c); }
  double MergeCost(uint32_t a, uint32_t b) const { return clusters_->MergeCost(a, b); }
  // Its neighbours and the clusters that list it as theirs: the dual edges are symmetric,
  // so when x's ODE is y, y sees x too and a chain of cheaper ODEs ends in a mutual pair
  // (PML merges only those; with one-sided edges a small cluster could wait behind far
  // costlier mutual pairs).
  template <typename F>
  void ForEachCandidate(uint32_t c, const F& f) const {
    if (clusters_->count(c) == 0) return;
    for (uint32_t n : clusters_->neighbours(c)) {
      if (n != kNone && clusters_->count(n) > 0) f(n);
    }
    for (uint32_t n : reverse_[c]) {
      if (n != kNone && clusters_->count(n) > 0) f(n);
    }
  }
  uint32_t TieKey(uint32_t /*c*/) const { return 0; }

  void Squash() {
    // The moved points in parallel blocks where a level moved many (the recorder's
    // blocks, joined in order: the same triplets).
    recorder_.Squash([&](uint32_t c) { return clusters_->Energy(c); },
                     [&](uint32_t i) { return clusters_->label(i); },
                     [&](uint32_t i) { return original_[i]; }, detail::TbbBlocks{1});
  }
  void EndLevel() {
    merged_.clear();
    gone_.clear();
  }
  LevelRecorder& recorder() { return recorder_; }

 private:
  // ---- neighbour bookkeeping --------------------------------------------------------------
  void Refresh(uint32_t c, std::vector<uint32_t>& candidates) {
    std::span<uint32_t> out = clusters_->neighbours(c);
    before_.assign(out.begin(), out.end());
    clusters_->RefreshNeighbours(c, candidates);
    for (uint32_t n : before_) {
      if (n == kNone) continue;
      auto& list = reverse_[n];
      auto it = std::find(list.begin(), list.end(), c);
      if (it != list.end()) {
        *it = list.back();
        list.pop_back();
      }
    }
    for (uint32_t n : out) {
      if (n != kNone) reverse_[n].push_back(c);
    }
    if (std::all_of(out.begin(), out.end(), [](uint32_t n) { return n == kNone; })) {
      LinkIsolated(c);
    }
  }

  // A live cluster left with no neighbours at all (an isolated occupied cell of the start,
  // or a group of clusters the others never listed that has merged into one) could never
  // merge again: it gets the nearest cluster in each subspace among all live clusters.
  // Rare (once per outlier cell or per such group), so a scan of all clusters is fine.
  void LinkIsolated(uint32_t c) {
    if (clusters_->count(c) == 0) return;
    std::vector<uint32_t> all;
    for (uint32_t n = 0; n < k0_; ++n) {
      if (n != c && clusters_->count(n) > 0) all.push_back(n);
    }
    if (all.empty()) return;
    clusters_->RefreshNeighbours(c, all);
    for (uint32_t n : clusters_->neighbours(c)) {
      if (n != kNone) reverse_[n].push_back(c);
    }
  }

 public:
  void Merge(uint32_t keep, uint32_t gone) {
    optimise_->Merge(keep, gone);
    into_[gone] = keep;
    partner_[keep] = gone;
    merged_.push_back(keep);
    gone_.push_back(gone);
  }

  // The CPU's checks of a round's slices (detail::PointOptimiseRounds::Run's stage): the
  // slices' work in tasks (of kSlicePoints members or more, see there), in parallel where
  // there is more than one; the moves (point, target) joined in slice order into `moves`:
  // the same list on any number of threads. A region slice: its points to check (Scan)
  // and their checks (CheckPoint, then Stamp). A slice of a cluster next to the merged
  // ones (round 0): each point against its own centroid and next_to's merged clusters
  // [compare_begin, compare_end), the nearest strictly closer one its target. Slices hold
  // distinct points, so each task stamps its own points only.
  void CheckSlices(std::span<const Slice> slices, std::span<const NextTo> next_to,
                   std::vector<Move>& moves) {
    tasks_.clear();
    size_t total = 0;
    for (const Slice& slice : slices) total += slice.end - slice.begin;
    const size_t task_points = std::max(kSlicePoints, total / kTasksPerPass);
    size_t size = 0, first = 0;
    for (size_t n = 0; n < slices.size(); ++n) {
      size += slices[n].end - slices[n].begin;
      if (size >= task_points) {
        tasks_.push_back({first, n + 1});
        first = n + 1;
        size = 0;
      }
    }
    if (first < slices.size()) tasks_.push_back({first, slices.size()});
    if (picked_.size() < tasks_.size()) picked_.resize(tasks_.size());
    const PointClusters& clusters = *clusters_;
    detail::PointOptimiseRounds& optimise = *optimise_;
    auto check = [&](Picked& out) {
      const size_t count = out.points.size();
      const uint32_t* points = out.points.data();
      out.targets.resize(count);
      out.margins.resize(count);
      uint32_t* targets = out.targets.data();
      double* margins = out.margins.data();
      for (size_t r = 0; r < count; ++r) {
        if (r + 8 < count) clusters.Prefetch(points[r + 8]);
        targets[r] = detail::CheckPoint<true>(clusters, points[r], out.x, margins[r]);
      }
      for (size_t r = 0; r < count; ++r) {
        const uint32_t i = points[r];
        optimise.Stamp(i, margins[r]);
        if (targets[r] != kNone) out.moves.push_back({i, targets[r]});
      }
      out.points.clear();
    };
    auto compare = [&](const Slice& slice, Picked& out) {
      const std::span<const uint32_t> list = optimise.members(slice.cluster);
      for (size_t at = slice.begin; at < slice.end; ++at) {
        const uint32_t i = list[at];
        if (at + 8 < slice.end) clusters.Prefetch(list[at + 8]);
        double best = clusters.Distance(i, slice.cluster);
        uint32_t to = kNone;
        for (uint32_t g = slice.compare_begin; g < slice.compare_end; ++g) {
          const double dist = clusters.Distance(i, next_to[g].second);
          if (dist < best) {
            best = dist;
            to = next_to[g].second;
          }
        }
        if (to != kNone) out.moves.push_back({i, to});
      }
    };
    auto run = [&](size_t t) {
      Picked& out = picked_[t];
      out.points.clear();
      out.moves.clear();
      std::pair<uint32_t, double> drift_of{kNone, 0.0};
      for (size_t n = tasks_[t].first; n < tasks_[t].last; ++n) {
        const Slice& slice = slices[n];
        if (slice.compare_end > slice.compare_begin) {
          check(out);  // the region's points before it, in order
          compare(slice, out);
          continue;
        }
        const size_t at = out.points.size();
        out.points.resize(at + (slice.end - slice.begin));
        out.points.resize(at + optimise.Scan(slice, out.points.data() + at, drift_of));
      }
      check(out);
    };
    if (tasks_.size() == 1) {
      run(0);
    } else {
      tbb::parallel_for(tbb::blocked_range<size_t>(0, tasks_.size(), 1), [&](const auto& range) {
        for (size_t t = range.begin(); t != range.end(); ++t) run(t);
      });
    }
    moves.clear();
    for (size_t t = 0; t < tasks_.size(); ++t) {
      moves.insert(moves.end(), picked_[t].moves.begin(), picked_[t].moves.end());
    }
  }

  // LN k-means around the merged clusters (detail/point_optimise.h's rounds) with the
  // CPU's checks (CheckSlices).
  void Optimise(std::span<const uint32_t> merged, bool /*parallel_level*/) {
    if (options_.optimizer == PointMultilevelOptions::Optimizer::kNone) return;
    // Cancelled: the engine reports it after the level.
    static_cast<void>(optimise_->Run(
        merged, options_.cancel,
        [&](std::span<const Slice> slices, std::span<const NextTo> next_to,
            std::vector<Move>& moves) {
          CheckSlices(slices, next_to, moves);
          return absl::OkStatus();
        },
        [](std::span<const uint32_t> /*changed*/, std::span<const Move> /*moved*/) {
          return absl::OkStatus();
        }));
  }

  // After a level: the neighbours of every cluster that changed and of those that saw a
  // changed or gone cluster are refreshed, and their ODEs recomputed.
  void UpdateOdes(Engine& engine) {
    std::vector<uint32_t> refresh;
    auto add = [&](uint32_t c) {
      if (!mark_[c] && clusters_->count(c) > 0) {
        mark_[c] = 1;
        refresh.push_back(c);
      }
    };
    std::vector<uint32_t> candidates;
    for (uint32_t gone : gone_) {
      for (uint32_t x : reverse_[gone]) add(x);
    }
    for (uint32_t c : recorder_.affected()) {
      add(c);
      for (uint32_t x : reverse_[c]) add(x);
    }
    // Candidates beyond a cluster's own second-order neighbours: after a few merges (ML),
    // every merged cluster and the gone ones' neighbours; after many (a PML step), where
    // offering all of them to every refreshed cluster would cost merges x refreshes, the
    // cluster each gone neighbour merged into and that one's neighbours, and to a merged
    // cluster its partner's neighbours.
    const bool few = merged_.size() <= 8;
    auto offer_neighbours_of = [&](uint32_t x) {
      for (uint32_t n : clusters_->neighbours(x)) {
        if (n != kNone) candidates.push_back(n);
      }
    };
    for (uint32_t c : refresh) {
      mark_[c] = 0;
      candidates.clear();
      if (few) {
        candidates.assign(merged_.begin(), merged_.end());
        for (uint32_t gone : gone_) offer_neighbours_of(gone);
      } else {
        if (partner_[c] != kNone) offer_neighbours_of(partner_[c]);
        for (uint32_t n : clusters_->neighbours(c)) {
          if (n == kNone || into_[n] == kNone) continue;
          candidates.push_back(into_[n]);
          offer_neighbours_of(n);
        }
      }
      Refresh(c, candidates);
    }
    for (uint32_t gone : gone_) {
      partner_[into_[gone]] = kNone;
      into_[gone] = kNone;
    }
    for (uint32_t gone : gone_) {
      for (uint32_t n : clusters_->neighbours(gone)) {
        if (n == kNone) continue;
        auto& list = reverse_[n];
        auto it = std::find(list.begin(), list.end(), gone);
        if (it != list.end()) {
          *it = list.back();
          list.pop_back();
        }
      }
      std::span<uint32_t> out = clusters_->neighbours(gone);
      std::fill(out.begin(), out.end(), kNone);
      engine.Invalidate(gone);
    }
    // ODEs: of the refreshed clusters, and of the clusters the changed ones list (to
    // which they are reverse neighbours).
    for (uint32_t c : recorder_.affected()) {
      for (uint32_t n : clusters_->neighbours(c)) {
        if (n != kNone && !mark_[n] && clusters_->count(n) > 0) {
          mark_[n] = 1;
          refresh_odes_.push_back(n);
        }
      }
    }
    for (uint32_t c : refresh) {
      if (!mark_[c]) {
        mark_[c] = 1;
        refresh_odes_.push_back(c);
      }
    }
    for (uint32_t c : refresh_odes_) mark_[c] = 0;
    engine.RecomputeOdes(refresh_odes_);
    refresh_odes_.clear();
  }

  // The labels of the level, in the caller's point order, to options_.inspect_level.
  void Inspect(size_t level) {
    if (!options_.inspect_level) return;
    std::vector<uint32_t> labels(original_.size());
    for (size_t i = 0; i < labels.size(); ++i) labels[original_[i]] = clusters_->label(i);
    options_.inspect_level(level, labels);
  }

  // When the local neighbours split the clusters into groups that never see each other,
  // give each surviving cluster its nearest cluster in each subspace among all survivors.
  bool ConnectWhenStuck(Engine& engine) {
    std::vector<uint32_t> survivors;
    for (uint32_t c = 0; c < k0_; ++c) {
      if (clusters_->count(c) > 0) survivors.push_back(c);
    }
    if (survivors.size() <= 1 || survivors.size() > 20000) return false;
    for (uint32_t c : survivors) {
      if (IsCancelled(options_.cancel)) return false;
      std::vector<uint32_t> candidates = survivors;
      Refresh(c, candidates);
    }
    bool any = false;
    for (uint32_t c : survivors) {
      engine.RecomputeOde(c);
      any = any || engine.partner(c) != kNone;
    }
    return any;
  }

 private:
  const PointSet& points_;
  PointSet sorted_;                 // points_ ordered by starting cell
  std::vector<uint32_t> original_;  // sorted_'s point -> points_'s
  const PointMultilevelOptions& options_;
  const uint32_t d_;
  uint32_t k0_ = 0;
  std::unique_ptr<PointClusters> clusters_;
  std::vector<std::vector<uint32_t>> reverse_;
  std::vector<uint8_t> mark_;
  LevelRecorder recorder_{0, 0};
  std::vector<uint32_t> merged_, gone_;
  // In the current level: the cluster each gone one merged into, and each merged one's
  // partner (kNone elsewhere).
  std::vector<uint32_t> into_, partner_;
  std::vector<uint32_t> refresh_odes_;
  std::vector<uint32_t> before_;  // Refresh's copy of the list it replaces
  // Optimise's rounds (member lists, bounds, apply) and CheckSlices' tasks (slices
  // [first, last)) and what each picked and chose. A pass makes tasks of at least
  // kSlicePoints members, and of 1/kTasksPerPass of its members where it has more: up to
  // about 13 us to check 256 points (about 50 ns each), so that TBB's cost per task (about
  // a microsecond) stays small, and enough tasks on 16 cores for a large pass.
  std::unique_ptr<detail::PointOptimiseRounds> optimise_;
  static constexpr size_t kSlicePoints = detail::PointOptimiseRounds::kSlicePoints;
  static constexpr size_t kTasksPerPass = 64;
  struct Task {
    size_t first, last;
  };
  std::vector<Task> tasks_;
  struct Picked {
    std::vector<uint32_t> points;
    std::vector<std::pair<uint32_t, uint32_t>> moves;
    std::vector<uint32_t> targets;  // scratch of the checks
    std::vector<double> margins, x;
  };
  std::vector<Picked> picked_;
};

}  // namespace

uint32_t SubspaceIndex(std::span<const double> from, std::span<const double> to) {
  uint32_t axis = 0;
  double largest = -1;
  for (uint32_t j = 0; j < from.size(); ++j) {
    const double diff = std::abs(to[j] - from[j]);
    if (diff > largest) {
      largest = diff;
      axis = j;
    }
  }
  return 2 * axis + (to[axis] > from[axis] ? 0 : 1);
}

absl::StatusOr<VoxelStart> VoxelGridStart(const PointSet& points, uint32_t grid,
                                          const std::atomic<bool>* cancel) {
  MLCLUST_RETURN_IF_ERROR(ValidatePoints(points));
  if (grid > (1u << 20)) {
    return absl::InvalidArgumentError(absl::StrCat("grid: ", grid, " is over 2^20"));
  }
  // The engine's own start (OccupiedCells), without the cell coordinates.
  const Bounds bounds = BoundsOf(points);
  VoxelCells cells =
      OccupiedCells(points, bounds, StartCells(points, bounds, grid, cancel), cancel);
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(cancel, "the voxel start"));
  VoxelStart start;
  start.clusters = static_cast<uint32_t>(cells.cell.size());
  start.labels.resize(cells.labels.size());
  for (size_t i = 0; i < cells.labels.size(); ++i) start.labels[i] = ClusterId(cells.labels[i]);
  return start;
}

absl::StatusOr<LnKmeansResult> RunLnKmeans(const PointSet& points, std::vector<ClusterId> labels,
                                           const LnKmeansOptions& options) {
  MLCLUST_RETURN_IF_ERROR(detail::CheckLnKmeansArguments(points, labels.size()));
  const size_t m = points.num_points();
  // Compact ids; remember the caller's.
  absl::flat_hash_map<uint32_t, uint32_t> compact_of;
  std::vector<uint32_t> compact(m);
  std::vector<ClusterId> original;
  for (size_t i = 0; i < m; ++i) {
    auto [it, inserted] =
        compact_of.try_emplace(labels[i].value(), static_cast<uint32_t>(original.size()));
    if (inserted) original.push_back(labels[i]);
    compact[i] = it->second;
  }
  const uint32_t k = static_cast<uint32_t>(original.size());
  tbb::task_arena arena(options.threads > 0 ? options.threads : tbb::task_arena::automatic);
  LnKmeansResult result;
  MLCLUST_RETURN_IF_ERROR(arena.execute([&]() -> absl::Status {
    PointClusters clusters(points, compact, k);
    InitialNeighbours(clusters, options.cancel);
    MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "LN k-means neighbours"));
    MLCLUST_RETURN_IF_ERROR(LnKmeansIterations(clusters, options, result));
    result.labels.resize(m);
    for (size_t i = 0; i < m; ++i) result.labels[i] = original[clusters.label(i)];
    return absl::OkStatus();
  }));
  return result;
}

absl::StatusOr<LnKmeansResult> RunLnKmeansFromGrid(const PointSet& points, uint32_t grid,
                                                   const LnKmeansOptions& options) {
  MLCLUST_RETURN_IF_ERROR(ValidatePoints(points));
  if (grid > (1u << 20)) {
    return absl::InvalidArgumentError(absl::StrCat("grid: ", grid, " is over 2^20"));
  }
  tbb::task_arena arena(options.threads > 0 ? options.threads : tbb::task_arena::automatic);
  LnKmeansResult result;
  MLCLUST_RETURN_IF_ERROR(arena.execute([&]() -> absl::Status {
    const Bounds bounds = BoundsOf(points);
    const VoxelCells cells = OccupiedCells(
        points, bounds, StartCells(points, bounds, grid, options.cancel), options.cancel);
    MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "the voxel start"));
    const uint32_t k = static_cast<uint32_t>(cells.cell.size());
    PointClusters clusters(points, cells.labels, k);
    VoxelNeighbours(cells, clusters, options.cancel);
    MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "the voxel start's neighbours"));
    MLCLUST_RETURN_IF_ERROR(LnKmeansIterations(clusters, options, result));
    result.labels.resize(points.num_points());
    for (size_t i = 0; i < result.labels.size(); ++i) {
      result.labels[i] = ClusterId(clusters.label(i));
    }
    return absl::OkStatus();
  }));
  return result;
}

absl::StatusOr<std::vector<float>> RandomPointCentres(const PointSet& points, uint32_t k,
                                                      uint64_t seed) {
  MLCLUST_RETURN_IF_ERROR(ValidatePoints(points));
  const size_t m = points.num_points();
  if (k < 1 || k > m) {
    return absl::InvalidArgumentError(
        absl::StrCat("clusters: ", k, " must be between 1 and the ", m, " points"));
  }
  Random random(seed);
  std::vector<uint32_t> all(m);
  std::iota(all.begin(), all.end(), 0);
  std::vector<float> centres;
  centres.reserve(size_t{k} * points.dims);
  for (uint32_t c = 0; c < k; ++c) {  // a partial Fisher-Yates shuffle
    const size_t j = c + random.Below(m - c);
    std::swap(all[c], all[j]);
    const std::span<const float> p = points.point(all[c]);
    centres.insert(centres.end(), p.begin(), p.end());
  }
  return centres;
}

absl::StatusOr<std::vector<ClusterId>> SeedPointClusters(const PointSet& points, uint32_t k,
                                                         bool kmeans_plus_plus, uint64_t seed,
                                                         int threads) {
  MLCLUST_RETURN_IF_ERROR(ValidatePoints(points));
  const size_t m = points.num_points();
  if (k < 1 || k > m) {
    return absl::InvalidArgumentError(
        absl::StrCat("clusters: ", k, " must be between 1 and the ", m, " points"));
  }
  // The centres: greedy k-means++ (core/kmeans.h), or k distinct random points.
  absl::StatusOr<std::vector<float>> chosen = kmeans_plus_plus
                                                  ? KmeansPlusPlusCentres(points, k, seed, threads)
                                                  : RandomPointCentres(points, k, seed);
  if (!chosen.ok()) return chosen.status();
  const std::vector<float> centres = *std::move(chosen);
  // Every point to its nearest centre: one assignment of core/kmeans.h's Lloyd (its
  // vectorised kernel; it also gives an empty cluster a point, so there are exactly k).
  KmeansOptions assign;
  assign.clusters = k;
  assign.max_iterations = 1;
  assign.threads = threads;
  absl::StatusOr<KmeansResult> assigned = RunLloyd(points, centres, assign);
  if (!assigned.ok()) return assigned.status();
  return std::move(assigned->labels);
}

// The text's start (PointMultilevelOptions::Start::kOptimisedGrid, Fig. 6.5 / 6.8): LN
// k-means on the voxel clusters, from their voxel neighbours as RunLnKmeansFromGrid; `cells`
// then holds its labels, the clusters it emptied dropped (with their cells).
namespace {
absl::Status OptimiseVoxelStart(const PointSet& points, const std::atomic<bool>* cancel,
                                VoxelCells& cells) {
  const uint32_t k = static_cast<uint32_t>(cells.cell.size());
  PointClusters clusters(points, cells.labels, k);
  VoxelNeighbours(cells, clusters, cancel);
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(cancel, "the voxel start's neighbours"));
  LnKmeansOptions options;
  options.cancel = cancel;
  LnKmeansResult result;
  MLCLUST_RETURN_IF_ERROR(LnKmeansIterations(clusters, options, result));
  std::vector<uint32_t> renumbered(k, kNone);
  std::vector<std::vector<uint32_t>> kept;
  for (uint32_t c = 0; c < k; ++c) {
    if (clusters.count(c) == 0) continue;
    renumbered[c] = static_cast<uint32_t>(kept.size());
    kept.push_back(std::move(cells.cell[c]));
  }
  cells.cell = std::move(kept);
  for (size_t i = 0; i < cells.labels.size(); ++i) cells.labels[i] = renumbered[clusters.label(i)];
  return absl::OkStatus();
}
}  // namespace

absl::StatusOr<PointMultilevelSummary> RunPointMultilevel(const PointSet& points,
                                                          const PointMultilevelOptions& options,
                                                          LevelSink& sink) {
  MLCLUST_RETURN_IF_ERROR(detail::CheckPointLevelsArguments(points, options));
  tbb::task_arena arena(options.threads > 0 ? options.threads : tbb::task_arena::automatic);
  return arena.execute([&]() -> absl::StatusOr<PointMultilevelSummary> {
    const Bounds bounds = BoundsOf(points);
    const std::vector<uint32_t> cells_per_axis =
        StartCells(points, bounds, options.grid, options.cancel);
    VoxelCells cells = OccupiedCells(points, bounds, cells_per_axis, options.cancel);
    MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "the voxel start"));
    if (options.start == PointMultilevelOptions::Start::kOptimisedGrid) {
      MLCLUST_RETURN_IF_ERROR(OptimiseVoxelStart(points, options.cancel, cells));
    }
    PointSpace space(points, options, cells);
    detail::MultilevelEngineOptions engine_options;
    engine_options.optimise = options.optimizer != PointMultilevelOptions::Optimizer::kNone;
    engine_options.parallel = options.parallel;
    engine_options.pml_until = options.pml_until;
    engine_options.pml_pairs = options.pml_pairs;
    engine_options.pairs_in_cost_order = true;
    engine_options.min_clusters = options.min_clusters;
    engine_options.cancel = options.cancel;
    detail::MultilevelEngine<PointSpace> engine(space, engine_options, sink);
    MLCLUST_ASSIGN_OR_RETURN(detail::MultilevelEngineSummary run, engine.Run());
    PointMultilevelSummary summary;
    summary.levels = run.levels;
    summary.start_clusters = space.start_clusters();
    summary.final_clusters = run.final_clusters;
    summary.moves = run.moves;
    summary.grid = *std::max_element(cells_per_axis.begin(), cells_per_axis.end());
    return summary;
  });
}

double PointEnergy(const PointSet& points, std::span<const ClusterId> labels) {
  const uint32_t d = points.dims;
  absl::flat_hash_map<uint32_t, std::pair<uint64_t, std::vector<double>>> means;
  for (size_t i = 0; i < labels.size(); ++i) {
    auto& [count, sum] = means[labels[i].value()];
    if (sum.empty()) sum.assign(d, 0.0);
    ++count;
    for (uint32_t j = 0; j < d; ++j) sum[j] += points.values[i * d + j];
  }
  for (auto& [c, entry] : means) {
    for (double& v : entry.second) v /= static_cast<double>(entry.first);
  }
  double energy = 0;
  for (size_t i = 0; i < labels.size(); ++i) {
    const std::vector<double>& mean = means[labels[i].value()].second;
    for (uint32_t j = 0; j < d; ++j) {
      const double diff = points.values[i * d + j] - mean[j];
      energy += diff * diff;
    }
  }
  return energy;
}

}  // namespace mlclust
