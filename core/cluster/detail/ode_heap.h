// The optimal dual edges (Def. 4.2) of the multilevel engines, and the queue that hands ML
// the cheapest of them.
//
// Per cluster: its ODE partner and the merge cost, and a version number. The queue holds
// (cost, cluster, version) entries and is lazy: recomputing a cluster's ODE pushes a new
// entry and bumps the version, so older entries of that cluster are skipped when popped
// (instead of the dissertation's O(k) scan for the cheapest ODE per merge). Stale entries
// pile up; once they outnumber the live clusters four to one the queue is rebuilt from
// the live ODEs, which keeps it O(clusters).
//
// Order: cheaper first; equal costs by a tie key the engine gives with each ODE, smaller
// first (the mesh engine: the cluster's face count, footnote 4 of section 4.2, l. 1588;
// 0 where no key is given), then the smaller cluster id, so every choice is
// deterministic. (Which partner a cluster's ODE names is CheaperDualEdge's rule: equal
// costs go to the larger id, as PML's.)
#ifndef MLCLUST_CORE_CLUSTER_DETAIL_ODE_HEAP_H_
#define MLCLUST_CORE_CLUSTER_DETAIL_ODE_HEAP_H_

#include <algorithm>
#include <cstdint>
#include <limits>
#include <vector>

#include "core/base/ids.h"

namespace mlclust::detail {

// "No cluster": a cluster without an ODE (no neighbour left). ClusterId's one sentinel
// (core/base/ids.h), named for the raw indices of the engine's tables.
inline constexpr uint32_t kNoCluster = ClusterId::kInvalidValue;

// Whether the dual edge to `candidate` at `cost` beats the best so far (`best_partner` at
// `best_cost`; kNoCluster when there is none yet): cheaper, or as cheap and to a larger
// id. The first candidate is taken even at an infinite cost.
inline bool CheaperDualEdge(double cost, uint32_t candidate, double best_cost,
                            uint32_t best_partner) {
  return cost < best_cost ||
         (cost == best_cost && best_partner != kNoCluster && candidate > best_partner) ||
         (best_partner == kNoCluster && cost <= best_cost);
}

class OdeHeap {
 public:
  explicit OdeHeap(uint32_t capacity)
      : partner_(capacity, kNoCluster),
        cost_(capacity, std::numeric_limits<double>::infinity()),
        tie_key_(capacity, 0),
        version_(capacity, 0) {}

  uint32_t capacity() const { return static_cast<uint32_t>(partner_.size()); }
  // Cluster c's ODE partner (kNoCluster: none) and the cost of merging them.
  uint32_t partner(uint32_t c) const { return partner_[c]; }
  double cost(uint32_t c) const { return cost_[c]; }
  size_t queued() const { return heap_.size(); }

  // Records c's ODE; its older queue entries become stale. With `queue` and a partner, c
  // is queued at `cost` with `tie_key` (see above).
  // (Inlined: called once per ODE change, in the engines' innermost loops.)
  [[gnu::always_inline]] inline void Set(uint32_t c, uint32_t partner, double cost,
                                         bool queue = true, uint32_t tie_key = 0) {
    partner_[c] = partner;
    cost_[c] = cost;
    tie_key_[c] = tie_key;
    ++version_[c];
    if (queue && partner != kNoCluster) {
      heap_.push_back({cost, tie_key, c, version_[c]});
      std::push_heap(heap_.begin(), heap_.end(), CheaperLast{});
    }
  }
  // Records c's ODE and nothing else (no version, no queue): for a pass that computes
  // every ODE at once, in parallel (one cluster per call), and rebuilds the queue after.
  void Assign(uint32_t c, uint32_t partner, double cost, uint32_t tie_key = 0) {
    partner_[c] = partner;
    cost_[c] = cost;
    tie_key_[c] = tie_key;
  }
  // Set's bookkeeping for an ODE recorded with Assign: c's older entries become stale and,
  // with `queue` and a partner, c is queued. Assign (in parallel) then Commit (in order)
  // is Set.
  void Commit(uint32_t c, bool queue) {
    ++version_[c];
    if (queue && partner_[c] != kNoCluster) {
      heap_.push_back({cost_[c], tie_key_[c], c, version_[c]});
      std::push_heap(heap_.begin(), heap_.end(), CheaperLast{});
    }
  }
  // Makes c's queue entries stale (a cluster that is gone).
  void Invalidate(uint32_t c) { ++version_[c]; }

  // The queue anew from the ODEs of the clusters `is_alive(c)` says are alive.
  template <typename IsAlive>
  void Rebuild(const IsAlive& is_alive) {
    heap_.clear();
    for (uint32_t c = 0; c < capacity(); ++c) {
      if (is_alive(c) && partner_[c] != kNoCluster) {
        heap_.push_back({cost_[c], tie_key_[c], c, version_[c]});
      }
    }
    std::make_heap(heap_.begin(), heap_.end(), CheaperLast{});
  }
  // Rebuilds once the stale entries outnumber the `alive` clusters four to one.
  template <typename IsAlive>
  void MaybeCompact(uint32_t alive, const IsAlive& is_alive) {
    if (heap_.size() > 4 * static_cast<size_t>(alive) + 4096) Rebuild(is_alive);
  }

  // The cluster whose ODE is the cheapest, its entry removed; kNoCluster once the queue
  // is empty. Entries of dead clusters and stale entries are dropped on the way.
  template <typename IsAlive>
  uint32_t PopCheapest(const IsAlive& is_alive) {
    while (!heap_.empty()) {
      std::pop_heap(heap_.begin(), heap_.end(), CheaperLast{});
      const Entry entry = heap_.back();
      heap_.pop_back();
      if (is_alive(entry.cluster) && version_[entry.cluster] == entry.version) {
        return entry.cluster;
      }
    }
    return kNoCluster;
  }

 private:
  // A cluster's ODE as it was when queued.
  struct Entry {
    double cost;
    uint32_t tie_key;
    uint32_t cluster;
    uint32_t version;
  };
  // std::push_heap keeps the largest on top; here x < y when x is dearer, or as dear and
  // of a larger tie key, or of equal keys and a larger id, so the top is the cheapest and,
  // among equals, the smallest key, then the smallest id.
  struct CheaperLast {
    bool operator()(const Entry& x, const Entry& y) const {
      if (x.cost != y.cost) return x.cost > y.cost;
      if (x.tie_key != y.tie_key) return x.tie_key > y.tie_key;
      return x.cluster > y.cluster;
    }
  };

  std::vector<uint32_t> partner_;
  std::vector<double> cost_;
  std::vector<uint32_t> tie_key_;
  std::vector<uint32_t> version_;
  std::vector<Entry> heap_;
};

}  // namespace mlclust::detail

#endif  // MLCLUST_CORE_CLUSTER_DETAIL_ODE_HEAP_H_
