#include "core/cluster/multilevel.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <queue>

#include "absl/container/flat_hash_map.h"
#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"
#include "core/base/status_macros.h"
#include "core/cluster/detail/emlo_impl.h"
#include "core/cluster/detail/ode_heap.h"
#include "core/cluster/partition.h"
#include "core/hierarchy/level_recorder.h"
#include "core/mesh/connectivity_guard.h"
#include "tbb/parallel_for.h"
#include "tbb/task_arena.h"

namespace mlclust {
namespace {

constexpr uint32_t kNone = detail::kNoCluster;

template <typename Energy>
class Engine {
 public:
  using Sums = typename Energy::Sums;
  using Proxy = typename Energy::Proxy;

  Engine(const MeshProblem& problem, const Energy& energy, const MultilevelOptions& options,
         LevelSink& sink)
      : adjacency_(*problem.adjacency),
        options_(options),
        sink_(sink),
        mesh_(*problem.mesh),
        n_(static_cast<uint32_t>(problem.mesh->num_faces())),
        partition_(energy, Identity(n_), n_),
        members_(n_),
        position_(n_, 0),
        neighbours_(n_),
        odes_(n_),
        dirty_mark_(n_, 0),
        recorder_(n_, n_) {}

  absl::StatusOr<MultilevelSummary> Run() {
    MLCLUST_RETURN_IF_ERROR(BuildClusterAdjacency());
    if (options_.connectivity_guard && options_.optimizer != MultilevelOptions::Optimizer::kNone) {
      // Only an optimiser needs the guard (HC never moves single faces); built here, between
      // cancellation checks, as it is the longest part of the set-up.
      MLCLUST_ASSIGN_OR_RETURN(ConnectivityGuard guard,
                               ConnectivityGuard::Build(mesh_, adjacency_, options_.cancel));
      guard_.emplace(std::move(guard));
    }
    std::vector<ClusterId> start(n_);
    for (uint32_t f = 0; f < n_; ++f) start[f] = ClusterId(f);
    MLCLUST_RETURN_IF_ERROR(sink_.OnStart(start, n_, 0.0));
    std::vector<ClusterId>().swap(start);
    summary_.levels = 1;
    if (options_.inspect_level) options_.inspect_level(0, partition_.labels());

    clusters_ = n_;
    // Alg. 4.2: below this count the merges are optimised.
    const double unoptimised = std::clamp(options_.p_percent, 0.0, 100.0) / 100.0;
    optimise_below_ = static_cast<uint32_t>(std::floor(n_ * (1.0 - unoptimised)));
    if (options_.p_percent > 0 &&
        options_.p_percent_rule == MultilevelOptions::PPercentRule::kSweep) {
      MLCLUST_RETURN_IF_ERROR(SweepMerges(n_ - optimise_below_));
      optimise_below_ = n_ + 1;  // the rest is ML
    }
    if (options_.optimizer == MultilevelOptions::Optimizer::kNone) optimise_below_ = 0;

    tbb::task_arena arena(options_.threads > 0 ? options_.threads : tbb::task_arena::automatic);
    bool odes_current = false;
    if (options_.parallel) {
      arena.execute([&] { ComputeAllOdes(); });
      odes_current = true;
      while (clusters_ > options_.min_clusters && clusters_ > options_.pml_until) {
        MLCLUST_RETURN_IF_ERROR(CheckLevelCancelled());
        absl::StatusOr<bool> progressed = arena.execute([&] { return ParallelStep(); });
        if (!progressed.ok()) return progressed.status();
        if (!*progressed) break;
      }
    }
    if (odes_current) {
      RebuildHeap();  // from the ODEs PML kept up to date
    } else {
      MLCLUST_RETURN_IF_ERROR(BuildHeap());
    }
    while (clusters_ > options_.min_clusters) {
      MLCLUST_RETURN_IF_ERROR(CheckLevelCancelled());
      absl::StatusOr<bool> progressed = SequentialStep();
      if (!progressed.ok()) return progressed.status();
      if (!*progressed) break;  // no adjacent pair left: one cluster per component
    }
    summary_.final_clusters = clusters_;
    summary_.final_energy = recorder_.energy();
    return summary_;
  }

 private:
  static std::vector<uint32_t> Identity(uint32_t n) {
    std::vector<uint32_t> ids(n);
    for (uint32_t i = 0; i < n; ++i) ids[i] = i;
    return ids;
  }

  // ---- cluster adjacency: per cluster, (neighbour, number of shared face edges) --------

  // One cluster per face: the clusters' adjacency is the faces'.
  absl::Status BuildClusterAdjacency() {
    for (uint32_t f = 0; f < n_; ++f) {
      if (f % 16384 == 0) MLCLUST_RETURN_IF_ERROR(CheckCancelled(options_.cancel, "ML set-up"));
      members_[f] = {f};
      for (FaceId g : adjacency_.neighbours[f]) {
        // Each face edge is seen from both faces: one side each time.
        if (g.valid() && g.value() != f) AddEdgesOneSide(f, g.value(), 1);
      }
    }
    return absl::OkStatus();
  }

  absl::Status CheckLevelCancelled() const {
    if (!IsCancelled(options_.cancel)) return absl::OkStatus();
    return CheckCancelled(options_.cancel, absl::StrCat("level ", summary_.levels));
  }

  void AddEdgesOneSide(uint32_t x, uint32_t z, int32_t delta) {
    auto& list = neighbours_[x];
    for (size_t i = 0; i < list.size(); ++i) {
      if (list[i].first == z) {
        list[i].second += delta;
        if (list[i].second == 0) {
          list[i] = list.back();
          list.pop_back();
          MarkDirty(x);  // x's ODE may have been the neighbour it no longer touches
        }
        return;
      }
    }
    if (delta > 0) list.push_back({z, static_cast<uint32_t>(delta)});
  }

  // Face f moved from y to x: each of its edges now borders x instead of y.
  void OnFaceMoved(uint32_t f, uint32_t y, uint32_t x) {
    for (FaceId g : adjacency_.neighbours[f]) {
      if (!g.valid()) continue;
      const uint32_t z = partition_.label(g.value());
      if (y != z) {
        AddEdgesOneSide(y, z, -1);
        AddEdgesOneSide(z, y, -1);
      }
      if (x != z) {
        AddEdgesOneSide(x, z, 1);
        AddEdgesOneSide(z, x, 1);
      }
    }
    // Members: swap-remove from y, append to x.
    auto& from = members_[y];
    const uint32_t at = position_[f];
    from[at] = from.back();
    position_[from[at]] = at;
    from.pop_back();
    position_[f] = static_cast<uint32_t>(members_[x].size());
    members_[x].push_back(f);
  }

  // ---- level bookkeeping ------------------------------------------------------------

  void Touch(uint32_t cluster) {
    recorder_.Touch(cluster, [&](uint32_t c) { return partition_.cluster_energy(c); });
  }
  void RecordMove(uint32_t face, uint32_t from) { recorder_.RecordMove(face, from); }

  // Merges `gone` into `keep` with all bookkeeping.
  void Merge(uint32_t keep, uint32_t gone) {
    Touch(keep);
    Touch(gone);
    for (uint32_t f : members_[gone]) RecordMove(f, gone);
    partition_.Merge(keep, gone, members_[gone]);
    for (uint32_t f : members_[gone]) {
      position_[f] = static_cast<uint32_t>(members_[keep].size());
      members_[keep].push_back(f);
    }
    std::vector<uint32_t>().swap(members_[gone]);
    for (const auto& [c, count] : neighbours_[gone]) {
      MarkDirty(c);  // its ODE may have been `gone`
      AddEdgesOneSide(c, gone, -static_cast<int32_t>(count));
      if (c == keep) continue;
      AddEdgesOneSide(keep, c, static_cast<int32_t>(count));
      AddEdgesOneSide(c, keep, static_cast<int32_t>(count));
    }
    std::vector<std::pair<uint32_t, uint32_t>>().swap(neighbours_[gone]);
    --clusters_;
  }
  // The larger cluster keeps its id (fewest faces move); the smaller id on a tie.
  std::pair<uint32_t, uint32_t> KeepAndGone(uint32_t a, uint32_t b) const {
    const uint32_t size_a = partition_.size(a), size_b = partition_.size(b);
    if (size_a > size_b || (size_a == size_b && a < b)) return {a, b};
    return {b, a};
  }

  // Local optimisation around the `merged` clusters, from their boundary faces outward.
  void Optimise(std::span<const uint32_t> merged) {
    if (clusters_ >= optimise_below_) return;
    worklist_.clear();
    for (uint32_t c : merged) {
      for (uint32_t f : members_[c]) {
        for (FaceId g : adjacency_.neighbours[f]) {
          if (g.valid() && partition_.label(g.value()) != c) {
            worklist_.push_back(f);
            break;
          }
        }
      }
    }
    const ConnectivityGuard* guard = guard_.has_value() ? &*guard_ : nullptr;
    // Touch (before each move) keeps the clusters' energies from before the level; this
    // runs after the move.
    auto on_move = [&](uint32_t face, uint32_t from, uint32_t to) {
      RecordMove(face, from);
      OnFaceMoved(face, from, to);
      ++summary_.optimisation_moves;
    };
    const uint64_t max_moves = 64 * static_cast<uint64_t>(worklist_.size()) + 1024;
    if (options_.optimizer == MultilevelOptions::Optimizer::kEmlo) {
      summary_.evaluations +=
          detail::RunEmloOn(
              adjacency_, guard, partition_, worklist_, max_moves, emlo_scratch_, on_move,
              [&](uint32_t from, uint32_t to) {
                Touch(from);
                Touch(to);
              },
              options_.cancel)
              .evaluations;
    } else {
      OptimiseBoundaryBased(guard, on_move);
    }
  }

  // Local boundary-based optimisation: sweeps over the worklist with the touched
  // clusters' proxies fixed per sweep; the faces that moved put their neighbours on the
  // next sweep's list. At most a few sweeps per level.
  template <typename OnMove>
  void OptimiseBoundaryBased(const ConnectivityGuard* guard, OnMove& on_move) {
    std::vector<uint32_t> next;
    for (int sweep = 0; sweep < 8 && !worklist_.empty(); ++sweep) {
      proxy_cache_.clear();
      auto proxy = [&](uint32_t c) -> const Proxy& {
        auto it = proxy_cache_.find(c);
        if (it == proxy_cache_.end()) {
          it = proxy_cache_.emplace(c, partition_.energy().FitProxy(partition_.sums(c))).first;
        }
        return it->second;
      };
      next.clear();
      for (uint32_t f : worklist_) {
        const uint32_t own = partition_.label(f);
        double best = partition_.energy().FaceCost(f, proxy(own));
        const double own_cost = best;
        uint32_t target = own;
        for (FaceId g : adjacency_.neighbours[f]) {
          if (!g.valid()) continue;
          const uint32_t c = partition_.label(g.value());
          if (c == own || c == target) continue;
          const double cost = partition_.energy().FaceCost(f, proxy(c));
          if (cost < best) {
            best = cost;
            target = c;
          }
        }
        if (target == own || own_cost - best <= 1e-12 * own_cost) continue;
        if (partition_.size(own) <= 1) continue;
        if (guard != nullptr &&
            !guard->CanMove(f, target, partition_.labels(), partition_.sizes())) {
          continue;
        }
        Touch(own);
        Touch(target);
        partition_.Move(f, target);
        on_move(f, own, target);
        for (FaceId g : adjacency_.neighbours[f]) {
          if (g.valid()) next.push_back(g.value());
        }
      }
      std::sort(next.begin(), next.end());
      next.erase(std::unique(next.begin(), next.end()), next.end());
      worklist_.swap(next);
    }
  }

  // Ends a level: squashes the moves into triplets, updates the energy, re-queues the
  // dual edges of every cluster that changed, and reports the level.
  absl::Status FinishLevel() {
    recorder_.Squash([&](uint32_t c) { return partition_.cluster_energy(c); },
                     [&](uint32_t f) { return partition_.label(f); }, [](uint32_t f) { return f; });
    if (!skip_ode_update_) UpdateOptimalDualEdges();
    for (uint32_t c : dirty_) dirty_mark_[c] = 0;
    dirty_.clear();
    MLCLUST_RETURN_IF_ERROR(recorder_.Emit(sink_, summary_.levels, clusters_));
    summary_.moves = recorder_.moves();
    if (options_.inspect_level) options_.inspect_level(summary_.levels, partition_.labels());
    ++summary_.levels;
    return absl::OkStatus();
  }

  // ---- ML: optimal dual edges and the cheapest of them from a heap ---------------------

  void MarkDirty(uint32_t c) {
    if (dirty_mark_[c]) return;
    dirty_mark_[c] = 1;
    dirty_.push_back(c);
  }

  double Cost(uint32_t a, uint32_t b) const {
    return partition_.energy().MergeCost(partition_.sums(a), partition_.sums(b));
  }

  // Equal costs go to the larger id (as PML's rule), so every choice is deterministic.
  static bool Better(double cost, uint32_t d, double best, uint32_t best_d) {
    return detail::CheaperDualEdge(cost, d, best, best_d);
  }

  // PML keeps the ODEs without queueing them; ML queues every new one.
  void SetOde(uint32_t c, uint32_t d, double cost) {
    odes_.Set(c, d, cost, /*queue=*/!in_parallel_phase_, TieKey(c));
  }
  bool Alive(uint32_t c) const { return partition_.size(c) > 0; }
  // Equal ODE costs: the cluster with the fewest faces first (footnote 4 of section 4.2,
  // l. 1588), or by id alone.
  uint32_t TieKey(uint32_t c) const {
    return options_.ties_to_fewest_faces ? partition_.size(c) : 0;
  }

  void RecomputeOde(uint32_t c) {
    double best = std::numeric_limits<double>::infinity();
    uint32_t best_d = kNone;
    for (const auto& [d, count] : neighbours_[c]) {
      const double cost = Cost(c, d);
      if (Better(cost, d, best, best_d)) {
        best = cost;
        best_d = d;
      }
    }
    SetOde(c, best_d, best);
  }

  // Section 4.2.2's flags: only clusters whose configuration changed (sums changed, or
  // their ODE partner changed or left) get their ODE recomputed; a neighbour of a changed
  // cluster only compares the one edge that changed, unless its ODE was that edge.
  void UpdateOptimalDualEdges() {
    for (uint32_t c : recorder_.affected()) MarkDirty(c);
    for (uint32_t c : dirty_) {
      if (partition_.size(c) > 0) RecomputeOde(c);
    }
    for (uint32_t c : recorder_.affected()) {
      if (partition_.size(c) == 0) continue;
      for (const auto& [d, count] : neighbours_[c]) {
        if (dirty_mark_[d]) continue;  // recomputed in full above
        if (odes_.partner(d) == c) {
          MarkDirty(d);  // its best edge changed: it may no longer be the best
          RecomputeOde(d);
          continue;
        }
        const double cost = Cost(d, c);
        if (Better(cost, c, odes_.cost(d), odes_.partner(d))) SetOde(d, c, cost);
      }
    }
    if (!in_parallel_phase_) {
      odes_.MaybeCompact(clusters_, [&](uint32_t c) { return Alive(c); });
    }
  }

  absl::Status BuildHeap() {
    for (uint32_t c = 0; c < n_; ++c) {
      if (c % 65536 == 0) {
        MLCLUST_RETURN_IF_ERROR(CheckCancelled(options_.cancel, "the first optimal dual edges"));
      }
      if (partition_.size(c) > 0) RecomputeOde(c);
    }
    return absl::OkStatus();
  }
  void RebuildHeap() {
    odes_.Rebuild([&](uint32_t c) { return Alive(c); });
  }

  absl::StatusOr<bool> SequentialStep() {
    const uint32_t cheapest = odes_.PopCheapest([&](uint32_t c) { return Alive(c); });
    if (cheapest == kNone) return false;
    const auto [keep, gone] = KeepAndGone(cheapest, odes_.partner(cheapest));
    Merge(keep, gone);
    const uint32_t merged[1] = {keep};
    Optimise(merged);
    MLCLUST_RETURN_IF_ERROR(FinishLevel());
    return true;
  }

  // ---- p% ML's first step (Alg. 4.2) ----------------------------------------------------

  // Merges `target` clusters (fewer if min_clusters or the components stop it) in one
  // level, without optimisation: sweeps over the clusters in id order, each one not yet in
  // a merge of the sweep collapsing its optimal dual edge (from the current sums, ties to
  // the larger id) unless the other cluster already took part in one; sweep after sweep
  // until `target` have merged (l. 1868-1872).
  absl::Status SweepMerges(uint32_t target) {
    const uint32_t floor = std::max(options_.min_clusters, 1u);
    target = std::min(target, clusters_ > floor ? clusters_ - floor : 0u);
    if (target == 0) return absl::OkStatus();
    std::vector<uint8_t> in_merge(n_, 0);
    std::vector<uint32_t> marked;
    uint32_t merged = 0;
    while (merged < target) {
      bool progressed = false;
      for (uint32_t c = 0; c < n_ && merged < target; ++c) {
        if (c % 65536 == 0) {
          MLCLUST_RETURN_IF_ERROR(CheckCancelled(options_.cancel, "the p% sweep"));
        }
        if (partition_.size(c) == 0 || in_merge[c]) continue;
        double best = std::numeric_limits<double>::infinity();
        uint32_t best_d = kNone;
        for (const auto& [d, count] : neighbours_[c]) {
          const double cost = Cost(c, d);
          if (Better(cost, d, best, best_d)) {
            best = cost;
            best_d = d;
          }
        }
        if (best_d == kNone || in_merge[best_d]) continue;
        const auto [keep, gone] = KeepAndGone(c, best_d);
        Merge(keep, gone);
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
    // One level; the ODEs are computed afresh after it (BuildHeap or ComputeAllOdes).
    skip_ode_update_ = true;
    absl::Status status = FinishLevel();
    skip_ode_update_ = false;
    return status;
  }

  // ---- PML: all mutual optimal dual edges at once --------------------------------------

  // All ODEs at once, in parallel (PML's start); no heap entries.
  void ComputeAllOdes() {
    alive_.clear();
    for (uint32_t c = 0; c < n_; ++c) {
      if (partition_.size(c) > 0) alive_.push_back(c);
    }
    tbb::parallel_for(tbb::blocked_range<size_t>(0, alive_.size(), 512),
                      [&](const tbb::blocked_range<size_t>& range) {
                        for (size_t i = range.begin(); i != range.end(); ++i) {
                          const uint32_t c = alive_[i];
                          double best = std::numeric_limits<double>::infinity();
                          uint32_t best_d = kNone;
                          for (const auto& [d, count] : neighbours_[c]) {
                            const double cost = Cost(c, d);
                            if (Better(cost, d, best, best_d)) {
                              best = cost;
                              best_d = d;
                            }
                          }
                          odes_.Assign(c, best_d, best, TieKey(c));
                        }
                      });
  }

  // One PML level: every cluster's ODE is up to date (ComputeAllOdes, then the flags of
  // each level); the mutual pairs collapse together. Equal costs go to the larger id,
  // which makes the order total, so the globally cheapest edge is always mutual.
  absl::StatusOr<bool> ParallelStep() {
    in_parallel_phase_ = true;
    size_t alive = 0;
    for (uint32_t c : alive_) {
      if (partition_.size(c) > 0) alive_[alive++] = c;
    }
    alive_.resize(alive);
    pairs_.clear();
    for (uint32_t c : alive_) {
      const uint32_t d = odes_.partner(c);
      if (d != kNone && c < d && odes_.partner(d) == c) pairs_.push_back({c, d});
    }
    if (pairs_.empty()) {
      in_parallel_phase_ = false;
      return false;
    }
    detail::SelectPmlPairs(
        options_.pml_pairs, [&](uint32_t c) { return odes_.cost(c); }, pairs_);
    // Do not merge past min_clusters / pml_until: the cheapest pairs first.
    const uint32_t floor = std::max(options_.min_clusters, 1u);
    if (clusters_ - pairs_.size() < floor) {
      std::sort(pairs_.begin(), pairs_.end(), [&](const auto& x, const auto& y) {
        return partition_.energy().MergeCost(partition_.sums(x.first), partition_.sums(x.second)) <
               partition_.energy().MergeCost(partition_.sums(y.first), partition_.sums(y.second));
      });
      pairs_.resize(clusters_ - floor);
    }
    merged_.clear();
    for (const auto& [a, b] : pairs_) {
      const auto [keep, gone] = KeepAndGone(a, b);
      Merge(keep, gone);
      merged_.push_back(keep);
    }
    if (clusters_ <= options_.pml_until) {
      // The hand-over to ML: one optimisation over every cluster's boundary, so that ML
      // continues from a state optimised as a whole, not only around the last merges.
      Optimise(alive_);
    } else {
      Optimise(merged_);
    }
    absl::Status s = FinishLevel();
    in_parallel_phase_ = false;
    if (!s.ok()) return s;
    return true;
  }

  const FaceAdjacency& adjacency_;
  const MultilevelOptions& options_;
  LevelSink& sink_;
  const TriangleMesh& mesh_;
  std::optional<ConnectivityGuard> guard_;  // with an optimiser and options.connectivity_guard
  const uint32_t n_;
  Partition<Energy> partition_;
  std::vector<std::vector<uint32_t>> members_;
  std::vector<uint32_t> position_;
  std::vector<std::vector<std::pair<uint32_t, uint32_t>>> neighbours_;
  detail::OdeHeap odes_;
  std::vector<uint8_t> dirty_mark_;
  std::vector<uint32_t> dirty_;

  LevelRecorder recorder_;
  uint32_t clusters_ = 0;
  uint32_t optimise_below_ = 0;
  bool in_parallel_phase_ = false;
  bool skip_ode_update_ = false;
  MultilevelSummary summary_;

  // Optimisation scratch.
  std::vector<uint32_t> worklist_;
  detail::EmloScratch emlo_scratch_;
  absl::flat_hash_map<uint32_t, Proxy> proxy_cache_;

  // PML scratch.
  std::vector<uint32_t> alive_, merged_;
  std::vector<std::pair<uint32_t, uint32_t>> pairs_;
};

}  // namespace

absl::StatusOr<MultilevelSummary> RunMultilevel(const MeshProblem& problem,
                                                const MultilevelOptions& options, LevelSink& sink) {
  if (problem.mesh == nullptr || problem.adjacency == nullptr || problem.measures == nullptr) {
    return absl::InvalidArgumentError("mesh problem without mesh, adjacency or measures");
  }
  MLCLUST_RETURN_IF_ERROR(ValidateMeshEnergyOptions(problem.energy));
  if (options.min_clusters < 1) {
    return absl::InvalidArgumentError("clusters: the lowest level must have at least 1");
  }
  if (!(options.p_percent >= 0 && options.p_percent <= 100)) {
    return absl::InvalidArgumentError(
        absl::StrCat("p-percent: ", options.p_percent, " is not in [0, 100]"));
  }
  if (options.threads < 0) {
    return absl::InvalidArgumentError(absl::StrCat("threads: ", options.threads, " < 0"));
  }
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "ML set-up"));
  return WithMeshEnergy(problem.energy, *problem.mesh, *problem.measures,
                        [&](const auto& energy) -> absl::StatusOr<MultilevelSummary> {
                          using Energy = std::decay_t<decltype(energy)>;
                          Engine<Energy> engine(problem, energy, options, sink);
                          return engine.Run();
                        });
}

}  // namespace mlclust
