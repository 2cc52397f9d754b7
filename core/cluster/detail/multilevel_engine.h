// The one multilevel engine (Alg. 4.1, 4.2, 5.3; HC as Alg. 2.3/2.6) over a "space": an
// energy and a neighbourhood together (mesh face adjacency in core/cluster/multilevel.cc,
// the points' local neighbours in core/cluster/point_clustering.cc). The engine owns the
// rules both share: the optimal dual edges (ODEs, Def. 4.2) and the lazy queue of
// detail/ode_heap.h, the ties rule (CheaperDualEdge: equal costs to the larger id; the
// queue's tie key and then the smaller id), which cluster keeps its id in a merge, ML's
// one merge per level, p% ML's first step (Alg. 4.2, sweep or hc-first), PML's mutual
// pairs (Alg. 5.3, the pair rule of detail/pml_pairs.h) and the level bookkeeping
// (core/hierarchy/level_recorder.h). The space owns what is its own: the clusters and
// their elements, who neighbours whom, the local optimisation, and which ODEs a level
// makes stale.
//
// A Space provides (c, d: cluster ids below capacity(); e: element indices):
//   uint32_t capacity() const;          cluster ids are below it
//   uint32_t start_clusters() const;    clusters at level 0
//   static constexpr bool kOptimiseAllAtHandover;  the PML level that reaches pml_until
//                                       optimises every cluster's boundary (mesh), or
//                                       only around its merges (points)
//   absl::Status ReportStart(LevelSink&);  set-up, level 0 to the sink, the recorder's
//                                       energy reset to level 0's
//   bool Alive(c) const; uint32_t Size(c) const;  (elements in c; 0 once merged away)
//   double MergeCost(c, d) const;       E(c u d) - E(c) - E(d) (eq. 4.1), c's sums first
//   void ForEachCandidate(c, f) const;  f(d) for every live cluster d that c may merge
//                                       with (duplicates allowed)
//   uint32_t TieKey(c) const;           the queue's tie key of c's ODE (0: none)
//   void Merge(keep, gone);             merges with all its bookkeeping (recorder too)
//   void MergePairs(span<const pair<uint32_t, uint32_t>> keep_gone);  optional: a PML
//                                       level's merges of disjoint pairs, the same as
//                                       Merge(keep, gone) pair after pair (in parallel
//                                       where it can)
//   void Optimise(span<const uint32_t> region, bool parallel_level);  local optimisation
//                                       around `region` (parallel_level: in a PML level)
//   void UpdateOdes(Engine&);           after a level: the ODEs the level made stale,
//                                       through Engine::RecomputeOdes / Offer
//   bool ConnectWhenStuck(Engine&);     no pair left but several clusters: link them and
//                                       return true, or false to stop
//   void Squash(); void EndLevel(); void Inspect(size_t level);
//   LevelRecorder& recorder();
//
// Parallel steps (PML: every ODE at the start and after each level, the mutual pairs) run
// on the caller's TBB arena; each writes only its own cluster's ODE from state no other
// step writes, so the levels do not depend on the number of threads.
#ifndef MLCLUST_CORE_CLUSTER_DETAIL_MULTILEVEL_ENGINE_H_
#define MLCLUST_CORE_CLUSTER_DETAIL_MULTILEVEL_ENGINE_H_

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"
#include "core/base/status_macros.h"
#include "core/cluster/detail/ode_heap.h"
#include "core/cluster/detail/pml_pairs.h"
#include "core/hierarchy/hierarchy.h"
#include "core/hierarchy/level_recorder.h"
#include "tbb/blocked_range.h"
#include "tbb/parallel_for.h"

namespace mlclust::detail {

struct MultilevelEngineOptions {
  // false: HC, merges only.
  bool optimise = true;
  // Alg. 4.2: the first p% of the merges without optimisation, in one sweep level
  // (p_percent_sweep) or one merge per level, cheapest first (hc-first).
  double p_percent = 0;
  bool p_percent_sweep = true;
  // Ours: with p%, the merges are optimised at least below this many clusters (0: p%
  // alone decides), so that a p% chosen for large inputs does not leave small ones
  // unoptimised.
  uint32_t optimise_below_at_least = 0;
  // PML (Alg. 5.3) while more than pml_until clusters are left, then ML.
  bool parallel = false;
  uint32_t pml_until = 0;
  PmlPairRule pml_pairs = PmlPairRule::kCheaperHalf;
  // The order in which a PML level's pairs merge: by cost, cheapest first (ties by pair),
  // or by the smaller cluster id. The merges of a level are disjoint, but the order of
  // the bookkeeping (and of the optimiser's work list) follows it.
  bool pairs_in_cost_order = false;
  uint32_t min_clusters = 1;
  const std::atomic<bool>* cancel = nullptr;
};

struct MultilevelEngineSummary {
  uint32_t levels = 0;  // level 0 included
  uint32_t final_clusters = 0;
  uint64_t moves = 0;
  double final_energy = 0;
};

// The face-order rounds' parallel steps (MeshSpace::ApplyRoundInSteps in
// core/cluster/multilevel.cc, ours): counts summed over all runs of the process, for
// benchmarks (bench/pml_cpu_bench prints them), and when the steps run. They give the
// levels of the loop they replace, so the mode changes no result, only the work: the steps
// cost about 40% more CPU than the loop on one core (BENCHMARKS.md, "The face-order rounds
// in parallel steps"), so by default they run only on an arena of at least
// kFaceOrderStepsFromThreads threads; kAlways is for tests that compare them with the loop
// and for profiles on one thread. Relaxed atomics.
struct FaceOrderStepsCounters {
  std::atomic<uint64_t> rounds{0};      // rounds run in steps
  std::atomic<uint64_t> steps{0};       // parallel steps
  std::atomic<uint64_t> candidates{0};  // candidates of those rounds
  std::atomic<uint64_t> in_steps{0};    // of which run in a parallel step (the rest: in order)
  std::atomic<uint64_t> moves{0};       // moves applied in those rounds
};
inline FaceOrderStepsCounters face_order_steps_counters;
enum class FaceOrderSteps : int { kFromFourThreads = 0, kAlways = 1, kNever = 2 };
inline constexpr int kFaceOrderStepsFromThreads = 4;
inline std::atomic<FaceOrderSteps> face_order_steps{FaceOrderSteps::kFromFourThreads};

// ODE computations in one parallel_for only above this many clusters (below it the
// set-up costs more than the work).
inline constexpr size_t kParallelOdeGrain = 256;

// LevelRecorder's for_blocks on TBB: body(begin, end) over [0, n) in ranges of about
// `grain` indices, run on the caller's arena.
struct TbbBlocks {
  size_t grain = 1;
  template <typename Body>
  void operator()(size_t n, const Body& body) const {
    tbb::parallel_for(
        tbb::blocked_range<size_t>(0, n, grain),
        [&](const tbb::blocked_range<size_t>& range) { body(range.begin(), range.end()); });
  }
};

// out = the indices i < n with keep(i), in order; in parallel blocks of 4096 where n is
// large (count per block, then each block fills its share): the same list either way.
template <typename Keep>
void CompactIndices(size_t n, const Keep& keep, std::vector<uint32_t>& out) {
  constexpr size_t kBlock = 4096;
  out.clear();
  if (n < 2 * kBlock) {
    for (size_t i = 0; i < n; ++i) {
      if (keep(i)) out.push_back(static_cast<uint32_t>(i));
    }
    return;
  }
  const size_t blocks = (n + kBlock - 1) / kBlock;
  std::vector<size_t> offset(blocks + 1, 0);
  tbb::parallel_for(size_t{0}, blocks, [&](size_t b) {
    size_t count = 0;
    for (size_t i = b * kBlock, end = std::min(n, (b + 1) * kBlock); i < end; ++i) {
      count += keep(i) ? 1 : 0;
    }
    offset[b + 1] = count;
  });
  for (size_t b = 0; b < blocks; ++b) offset[b + 1] += offset[b];
  out.resize(offset[blocks]);
  tbb::parallel_for(size_t{0}, blocks, [&](size_t b) {
    size_t at = offset[b];
    for (size_t i = b * kBlock, end = std::min(n, (b + 1) * kBlock); i < end; ++i) {
      if (keep(i)) out[at++] = static_cast<uint32_t>(i);
    }
  });
}

template <typename Space>
class MultilevelEngine {
 public:
  MultilevelEngine(Space& space, const MultilevelEngineOptions& options, LevelSink& sink)
      : space_(space), options_(options), sink_(sink), odes_(space.capacity()) {}

  absl::StatusOr<MultilevelEngineSummary> Run() {
    MLCLUST_RETURN_IF_ERROR(space_.ReportStart(sink_));
    clusters_ = space_.start_clusters();
    levels_ = 1;
    space_.Inspect(0);
    const uint32_t start = clusters_;
    // Alg. 4.2: below this count the merges are optimised.
    const double unoptimised = std::clamp(options_.p_percent, 0.0, 100.0) / 100.0;
    optimise_below_ = std::max(static_cast<uint32_t>(std::floor(start * (1.0 - unoptimised))),
                               options_.optimise_below_at_least);
    if (options_.p_percent > 0 && options_.p_percent_sweep) {
      MLCLUST_RETURN_IF_ERROR(SweepMerges(start - optimise_below_));
      optimise_below_ = start + 1;  // the rest is ML
    }
    if (!options_.optimise) optimise_below_ = 0;
    MLCLUST_RETURN_IF_ERROR(ComputeAllOdes());
    while (clusters_ > options_.min_clusters) {
      MLCLUST_RETURN_IF_ERROR(CheckLevelCancelled());
      bool merged = false;
      if (options_.parallel && clusters_ > options_.pml_until) merged = ParallelMerges();
      // ML, or a PML level without a mutual pair (one merge instead).
      if (!merged) merged = SequentialMerge();
      if (!merged) {
        // No pair left: one cluster per component, unless the space can link them.
        if (!space_.ConnectWhenStuck(*this)) break;
        continue;
      }
      MLCLUST_RETURN_IF_ERROR(FinishLevel());
    }
    MLCLUST_RETURN_IF_ERROR(CheckLevelCancelled());  // ConnectWhenStuck may have stopped
    MultilevelEngineSummary summary;
    summary.levels = levels_;
    summary.final_clusters = clusters_;
    summary.moves = space_.recorder().moves();
    summary.final_energy = space_.recorder().energy();
    return summary;
  }

  // ---- for the space's UpdateOdes and ConnectWhenStuck ---------------------------------

  uint32_t partner(uint32_t c) const { return odes_.partner(c); }
  double cost(uint32_t c) const { return odes_.cost(c); }
  void Invalidate(uint32_t c) { odes_.Invalidate(c); }

  // c's ODE from scratch: the cheapest candidate, equal costs to the larger id.
  void RecomputeOde(uint32_t c) {
    const auto [partner, cost] = FindOde(c);
    odes_.Set(c, partner, cost, /*queue=*/heap_current_, space_.TieKey(c));
  }
  // The ODEs of `clusters` (distinct) from scratch: in parallel where there are many, in
  // order otherwise; the same result either way.
  void RecomputeOdes(std::span<const uint32_t> clusters) {
    if (clusters.size() < kParallelOdeGrain) {
      for (uint32_t c : clusters) RecomputeOde(c);
      return;
    }
    tbb::parallel_for(tbb::blocked_range<size_t>(0, clusters.size(), 128),
                      [&](const tbb::blocked_range<size_t>& range) {
                        for (size_t i = range.begin(); i != range.end(); ++i) {
                          const uint32_t c = clusters[i];
                          const auto [partner, cost] = FindOde(c);
                          odes_.Assign(c, partner, cost, space_.TieKey(c));
                        }
                      });
    for (uint32_t c : clusters) odes_.Commit(c, heap_current_);
  }
  // The dual edge (d, c) changed while d's ODE did not point at c: d takes it if cheaper.
  void Offer(uint32_t d, uint32_t c) {
    const double cost = space_.MergeCost(d, c);
    if (CheaperDualEdge(cost, c, odes_.cost(d), odes_.partner(d))) {
      odes_.Set(d, c, cost, /*queue=*/heap_current_, space_.TieKey(d));
    }
  }
  // c's ODE as it would be recomputed, without recording it (pure; safe in parallel).
  std::pair<uint32_t, double> FindOde(uint32_t c) const {
    double best = std::numeric_limits<double>::infinity();
    uint32_t best_d = kNoCluster;
    space_.ForEachCandidate(c, [&](uint32_t d) {
      const double cost = space_.MergeCost(c, d);
      if (CheaperDualEdge(cost, d, best, best_d)) {
        best = cost;
        best_d = d;
      }
    });
    return {best_d, best};
  }
  // Whether the engine is in a PML level (its ODE updates are not queued).
  bool in_parallel_level() const { return !heap_current_; }
  // In a PML level only: records c's ODE as found by the space (FindOde's rule); distinct
  // clusters may be assigned from parallel tasks.
  void AssignOde(uint32_t c, uint32_t partner, double cost) {
    odes_.Assign(c, partner, cost, space_.TieKey(c));
  }

 private:
  bool Alive(uint32_t c) const { return space_.Alive(c); }

  absl::Status CheckLevelCancelled() const {
    if (!IsCancelled(options_.cancel)) return absl::OkStatus();
    return CheckCancelled(options_.cancel, absl::StrCat("level ", levels_));
  }

  // The larger cluster keeps its id (fewest elements move); the smaller id on a tie.
  std::pair<uint32_t, uint32_t> KeepAndGone(uint32_t a, uint32_t b) const {
    const uint32_t size_a = space_.Size(a), size_b = space_.Size(b);
    if (size_a > size_b || (size_a == size_b && a < b)) return {a, b};
    return {b, a};
  }
  void Merge(uint32_t a, uint32_t b) {
    const auto [keep, gone] = KeepAndGone(a, b);
    space_.Merge(keep, gone);
    --clusters_;
    merged_.push_back(keep);
  }

  // Local optimisation after the level's merges, unless p% or HC says not yet / never.
  void Optimise(bool handover) {
    if (clusters_ >= optimise_below_) return;
    if (handover && Space::kOptimiseAllAtHandover) {
      // The hand-over to ML: one optimisation over every cluster's boundary, so that ML
      // continues from a state optimised as a whole, not only around the last merges.
      space_.Optimise(alive_, !heap_current_);
    } else {
      space_.Optimise(merged_, !heap_current_);
    }
  }

  // Every live cluster's ODE, in parallel; the queue is built when ML first needs it.
  absl::Status ComputeAllOdes() {
    alive_.clear();
    for (uint32_t c = 0; c < space_.capacity(); ++c) {
      if (Alive(c)) alive_.push_back(c);
    }
    tbb::parallel_for(tbb::blocked_range<size_t>(0, alive_.size(), 512),
                      [&](const tbb::blocked_range<size_t>& range) {
                        if (IsCancelled(options_.cancel)) return;
                        for (size_t i = range.begin(); i != range.end(); ++i) {
                          const uint32_t c = alive_[i];
                          const auto [partner, cost] = FindOde(c);
                          odes_.Assign(c, partner, cost, space_.TieKey(c));
                        }
                      });
    heap_current_ = false;
    return CheckCancelled(options_.cancel, "the first optimal dual edges");
  }

  // ML (Alg. 4.1): the cheapest ODE of all merges.
  bool SequentialMerge() {
    if (!heap_current_) {
      odes_.Rebuild([&](uint32_t c) { return Alive(c); });
      heap_current_ = true;
    }
    merged_.clear();
    for (;;) {
      const uint32_t cheapest = odes_.PopCheapest([&](uint32_t c) { return Alive(c); });
      if (cheapest == kNoCluster) return false;
      const uint32_t other = odes_.partner(cheapest);
      if (other == kNoCluster || !Alive(other)) {
        RecomputeOde(cheapest);
        continue;
      }
      Merge(cheapest, other);
      Optimise(/*handover=*/false);
      return true;
    }
  }

  // PML (Alg. 5.3): every mutual pair of ODEs (the rule's share of them) merges in one
  // level. Equal costs go to the larger id, which makes the order total, so the globally
  // cheapest edge is always mutual. False where there is no mutual pair.
  bool ParallelMerges() {
    heap_current_ = false;
    size_t alive = 0;
    for (uint32_t c : alive_) {
      if (Alive(c)) alive_[alive++] = c;
    }
    alive_.resize(alive);
    FindMutualPairs();
    if (pairs_.empty()) return false;
    auto cheaper = [&](const std::pair<uint32_t, uint32_t>& x,
                       const std::pair<uint32_t, uint32_t>& y) {
      const double cx = odes_.cost(x.first), cy = odes_.cost(y.first);
      return cx != cy ? cx < cy : x < y;
    };
    if (options_.pairs_in_cost_order) std::sort(pairs_.begin(), pairs_.end(), cheaper);
    SelectPmlPairs(
        options_.pml_pairs, [&](uint32_t c) { return odes_.cost(c); }, pairs_, pair_costs_);
    // Do not merge past min_clusters: the cheapest pairs first.
    const uint32_t floor = std::max(options_.min_clusters, 1u);
    if (clusters_ - pairs_.size() < floor) {
      if (!options_.pairs_in_cost_order) std::sort(pairs_.begin(), pairs_.end(), cheaper);
      pairs_.resize(clusters_ - floor);
    }
    merged_.clear();
    if constexpr (requires {
                    space_.MergePairs(std::span<const std::pair<uint32_t, uint32_t>>());
                  }) {
      // The pairs are disjoint: which cluster keeps its id does not depend on the others'
      // merges, so it is decided for all first and the space merges them together.
      for (auto& pair : pairs_) {
        pair = KeepAndGone(pair.first, pair.second);
        merged_.push_back(pair.first);
      }
      space_.MergePairs(pairs_);
      clusters_ -= static_cast<uint32_t>(pairs_.size());
    } else {
      for (const auto& [a, b] : pairs_) Merge(a, b);
    }
    Optimise(/*handover=*/clusters_ <= options_.pml_until);
    return true;
  }

  // The mutual pairs (c, partner(c)) with c < partner(c), in order of c (Alg. 5.8: each
  // pair found once, from one side); in parallel over blocks of the live clusters, the
  // blocks' finds joined in block order.
  void FindMutualPairs() {
    pairs_.clear();
    auto mutual = [&](uint32_t c) {
      const uint32_t d = odes_.partner(c);
      return d != kNoCluster && c < d && Alive(d) && odes_.partner(d) == c;
    };
    constexpr size_t kBlock = 4096;
    const size_t blocks = (alive_.size() + kBlock - 1) / kBlock;
    if (blocks <= 1) {
      for (uint32_t c : alive_) {
        if (mutual(c)) pairs_.push_back({c, odes_.partner(c)});
      }
      return;
    }
    block_pairs_.resize(blocks);
    tbb::parallel_for(size_t{0}, blocks, [&](size_t b) {
      auto& found = block_pairs_[b];
      found.clear();
      const size_t end = std::min(alive_.size(), (b + 1) * kBlock);
      for (size_t i = b * kBlock; i < end; ++i) {
        if (mutual(alive_[i])) found.push_back({alive_[i], odes_.partner(alive_[i])});
      }
    });
    for (const auto& found : block_pairs_) pairs_.insert(pairs_.end(), found.begin(), found.end());
  }

  // Alg. 4.2's first step: merges `target` clusters (fewer if min_clusters or the
  // components stop it) in one level, without optimisation: sweeps over the clusters in id
  // order, each one not yet in a merge of the sweep collapsing its optimal dual edge (from
  // the current sums, ties to the larger id) unless the other cluster already took part in
  // one; sweep after sweep until `target` have merged (l. 1868-1872).
  absl::Status SweepMerges(uint32_t target) {
    const uint32_t floor = std::max(options_.min_clusters, 1u);
    target = std::min(target, clusters_ > floor ? clusters_ - floor : 0u);
    if (target == 0) return absl::OkStatus();
    const uint32_t capacity = space_.capacity();
    std::vector<uint8_t> in_merge(capacity, 0);
    std::vector<uint32_t> marked;
    uint32_t merged = 0;
    while (merged < target) {
      bool progressed = false;
      for (uint32_t c = 0; c < capacity && merged < target; ++c) {
        if (c % 65536 == 0) {
          MLCLUST_RETURN_IF_ERROR(CheckCancelled(options_.cancel, "the p% sweep"));
        }
        if (!Alive(c) || in_merge[c]) continue;
        const uint32_t best_d = FindOde(c).first;
        if (best_d == kNoCluster || in_merge[best_d]) continue;
        const auto [keep, gone] = KeepAndGone(c, best_d);
        space_.Merge(keep, gone);
        --clusters_;
        in_merge[keep] = in_merge[gone] = 1;
        marked.push_back(keep);
        marked.push_back(gone);
        ++merged;
        progressed = true;
      }
      for (uint32_t c : marked) in_merge[c] = 0;
      marked.clear();
      if (!progressed) break;  // one cluster per component
    }
    // One level; the ODEs are computed afresh after it (ComputeAllOdes).
    skip_ode_update_ = true;
    absl::Status status = FinishLevel();
    skip_ode_update_ = false;
    return status;
  }

  // Ends a level: squashes the moves into triplets and updates the energy, brings the
  // ODEs the level made stale up to date, and reports the level.
  absl::Status FinishLevel() {
    space_.Squash();
    if (!skip_ode_update_) {
      space_.UpdateOdes(*this);
      if (heap_current_) odes_.MaybeCompact(clusters_, [&](uint32_t c) { return Alive(c); });
    }
    space_.EndLevel();
    MLCLUST_RETURN_IF_ERROR(space_.recorder().Emit(sink_, levels_, clusters_));
    space_.Inspect(levels_);
    ++levels_;
    return absl::OkStatus();
  }

  Space& space_;
  const MultilevelEngineOptions& options_;
  LevelSink& sink_;
  OdeHeap odes_;
  // Whether the queue holds every live cluster's current ODE (ML); PML levels keep the
  // ODEs only, and the queue is rebuilt from them when ML next needs it.
  bool heap_current_ = false;
  bool skip_ode_update_ = false;
  uint32_t clusters_ = 0, levels_ = 0, optimise_below_ = 0;
  std::vector<uint32_t> alive_, merged_;
  std::vector<std::pair<uint32_t, uint32_t>> pairs_;
  std::vector<double> pair_costs_;  // SelectPmlPairs' scratch
  std::vector<std::vector<std::pair<uint32_t, uint32_t>>> block_pairs_;
};

}  // namespace mlclust::detail

#endif  // MLCLUST_CORE_CLUSTER_DETAIL_MULTILEVEL_ENGINE_H_
