#include "core/cluster/multilevel.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <optional>
#include <queue>
#include <type_traits>

#include "absl/container/flat_hash_map.h"
#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"
#include "core/base/status_macros.h"
#include "core/base/tolerance.h"
#include "core/cluster/boundary_based.h"
#include "core/cluster/detail/emlo_impl.h"
#include "core/cluster/detail/member_lists.h"
#include "core/cluster/detail/multilevel_engine.h"
#include "core/cluster/detail/polygon_energy.h"
#include "core/cluster/partition.h"
#include "core/hierarchy/level_recorder.h"
#include "core/mesh/connectivity_guard.h"
#include "tbb/blocked_range.h"
#include "tbb/parallel_for.h"
#include "tbb/parallel_sort.h"
#include "tbb/task_arena.h"

namespace mlclust {
namespace {

// ConnectivityGuard::Build on the caller's TBB arena: every face's ring is BuildFaceRing's,
// built in blocks of 16,384 faces in parallel and joined in face order at prefix offsets,
// so the guard is the one Build gives (which builds them one by one, 4-12% of a PML run's
// work on one core: BENCHMARKS.md, "Less sequential work per level"). Cancellation is
// checked per block.
absl::StatusOr<ConnectivityGuard> BuildConnectivityGuardInParallel(
    const TriangleMesh& mesh, const FaceAdjacency& adjacency, const std::atomic<bool>* cancel) {
  const size_t n = adjacency.num_faces();
  constexpr size_t kBlock = 16384;
  const size_t blocks = (n + kBlock - 1) / kBlock;
  std::vector<std::vector<uint32_t>> block_rings(blocks);
  std::vector<uint64_t> offset(n + 1, 0);
  tbb::parallel_for(size_t{0}, blocks, [&](size_t b) {
    if (IsCancelled(cancel)) return;
    const size_t begin = b * kBlock, end = std::min(n, begin + kBlock);
    std::vector<uint32_t>& rings = block_rings[b];
    rings.reserve(13 * (end - begin));
    std::vector<uint32_t> ring;
    for (size_t f = begin; f < end; ++f) {
      BuildFaceRing(mesh, adjacency, static_cast<uint32_t>(f), ring);
      rings.insert(rings.end(), ring.begin(), ring.end());
      offset[f + 1] = rings.size();  // within the block; the block's base is added below
    }
  });
  if (IsCancelled(cancel)) {
    return absl::CancelledError("cancelled while building the connectivity guard");
  }
  std::vector<uint64_t> base(blocks + 1, 0);
  for (size_t b = 0; b < blocks; ++b) base[b + 1] = base[b] + block_rings[b].size();
  std::vector<uint32_t> elements(base[blocks]);
  tbb::parallel_for(size_t{0}, blocks, [&](size_t b) {
    const size_t begin = b * kBlock, end = std::min(n, begin + kBlock);
    for (size_t f = begin; f < end; ++f) offset[f + 1] += base[b];
    std::copy(block_rings[b].begin(), block_rings[b].end(), elements.begin() + base[b]);
    std::vector<uint32_t>().swap(block_rings[b]);
  });
  return ConnectivityGuard::FromRings(std::move(offset), std::move(elements));
}

// The mesh's space for the multilevel engine (detail/multilevel_engine.h): clusters of
// faces, neighbours across face edges, EMLO or BB as the local optimisation. With
// problem.polygons (Adjacency = PolygonAdjacency, Energy a detail::PolygonEnergy) the
// elements are the polygons: level 0 is one cluster per polygon, with its energy.
template <typename Energy, typename Adjacency = FaceAdjacency>
class MeshSpace {
 public:
  using Proxy = typename Energy::Proxy;
  using Engine = detail::MultilevelEngine<MeshSpace>;
  static constexpr bool kOptimiseAllAtHandover = true;

  MeshSpace(const MeshProblem& problem, const Energy& energy, const MultilevelOptions& options,
            const Adjacency& adjacency)
      : adjacency_(adjacency),
        options_(options),
        mesh_(*problem.mesh),
        problem_(problem),
        n_(static_cast<uint32_t>(adjacency.num_faces())),
        partition_(energy, Identity(n_), n_),
        exact_sums_(n_),
        exact_energy_(n_, 0.0),
        shrunk_mark_(n_, 0),
        members_(n_),
        position_(n_, 0),
        neighbours_(n_),
        dirty_mark_(n_, 0),
        affected_mark_(n_, 0),
        check_mark_(n_, 0),
        round_mark_(n_, 0),
        recorder_(n_, n_) {}

  uint32_t capacity() const { return n_; }
  uint32_t start_clusters() const { return n_; }
  uint64_t optimisation_moves() const { return optimisation_moves_; }
  uint64_t evaluations() const { return evaluations_; }

  // Level 0: every face its own cluster, energy 0 for every energy here.
  absl::Status ReportStart(LevelSink& sink) {
    MLCLUST_RETURN_IF_ERROR(BuildClusterAdjacency());
    for (uint32_t c = 0; c < n_; ++c) {
      exact_sums_[c] = partition_.sums(c);
      exact_energy_[c] = partition_.cluster_energy(c);
    }
    if constexpr (!std::is_same_v<Adjacency, FaceAdjacency>) {
      // Polygons (RunMultilevel refused Alg. 3.2's per-triangle counts): their ring test.
      if (options_.connectivity_guard && options_.guard != ConnectivityGuardKind::kOff &&
          options_.optimizer != MultilevelOptions::Optimizer::kNone) {
        MLCLUST_ASSIGN_OR_RETURN(ConnectivityGuard guard, BuildPolygonConnectivityGuard(
                                                              mesh_, *problem_.adjacency,
                                                              *problem_.polygons, options_.cancel));
        guard_.emplace(std::move(guard));
      }
      std::vector<ClusterId> start(n_);
      for (uint32_t p = 0; p < n_; ++p) start[p] = ClusterId(p);
      recorder_.Reset(partition_.TotalEnergy());
      return sink.OnStart(start, n_, partition_.TotalEnergy());
    } else if (options_.connectivity_guard &&
               options_.optimizer != MultilevelOptions::Optimizer::kNone &&
               options_.guard == ConnectivityGuardKind::kVertexBoundaryEdgeCount) {
      vertex_count_guard_.emplace(mesh_, adjacency_);
    } else if (options_.connectivity_guard && options_.guard != ConnectivityGuardKind::kOff &&
               options_.optimizer != MultilevelOptions::Optimizer::kNone) {
      // Only an optimiser needs the guard (HC never moves single faces); built here, between
      // cancellation checks, as it is the longest part of the set-up.
      MLCLUST_ASSIGN_OR_RETURN(ConnectivityGuard guard, BuildConnectivityGuardInParallel(
                                                            mesh_, adjacency_, options_.cancel));
      guard_.emplace(std::move(guard));
    }
    std::vector<ClusterId> start(n_);
    for (uint32_t f = 0; f < n_; ++f) start[f] = ClusterId(f);
    recorder_.Reset(0.0);
    return sink.OnStart(start, n_, 0.0);
  }

  bool Alive(uint32_t c) const { return partition_.size(c) > 0; }
  uint32_t Size(uint32_t c) const { return partition_.size(c); }
  double MergeCost(uint32_t a, uint32_t b) const {
    return partition_.energy().MergeCost(partition_.sums(a), partition_.sums(b));
  }
  template <typename F>
  void ForEachCandidate(uint32_t c, const F& f) const {
    for (const auto& [d, count] : neighbours_[c]) f(d);
  }
  // Equal ODE costs: the cluster with the fewest faces first (footnote 4 of section 4.2,
  // l. 1588), or by id alone.
  uint32_t TieKey(uint32_t c) const {
    return options_.ties_to_fewest_faces ? partition_.size(c) : 0;
  }

  // Merges `gone` into `keep` with all bookkeeping.
  void Merge(uint32_t keep, uint32_t gone) {
    Touch(keep);
    Touch(gone);
    for (uint32_t f : members_[gone]) recorder_.RecordMove(f, gone);
    partition_.Merge(keep, gone, members_[gone]);
    MergeExactSums(keep, gone);
    for (uint32_t f : members_[gone]) {
      position_[f] = static_cast<uint32_t>(members_[keep].size());
      members_[keep].push_back(f);
    }
    std::vector<uint32_t>().swap(members_[gone]);
    MergeNeighbours(keep, gone);
  }

  // A PML level's merges of disjoint pairs (keep, gone), the same as Merge pair after
  // pair: the recorder's moves, the sums and labels and the members for all pairs at once
  // (each pair writes only its own clusters and faces), then the neighbour lists, which
  // pairs share, in pair order.
  void MergePairs(std::span<const std::pair<uint32_t, uint32_t>> keep_gone) {
    const detail::TbbBlocks blocks{/*grain=*/32};
    if (keep_gone.size() < detail::kParallelOdeGrain ||
        !recorder_.RecordMerges(
            keep_gone, [&](uint32_t c) { return exact_energy_[c]; },
            [&](uint32_t c) { return std::span<const uint32_t>(members_[c]); }, blocks)) {
      for (const auto& [keep, gone] : keep_gone) Merge(keep, gone);
      return;
    }
    blocks(keep_gone.size(), [&](size_t begin, size_t end) {
      for (size_t i = begin; i < end; ++i) {
        const auto [keep, gone] = keep_gone[i];
        partition_.MergeUncounted(keep, gone, members_[gone]);
        MergeExactSums(keep, gone);
        std::vector<uint32_t>& kept = members_[keep];
        for (uint32_t f : members_[gone]) {
          position_[f] = static_cast<uint32_t>(kept.size());
          kept.push_back(f);
        }
        std::vector<uint32_t>().swap(members_[gone]);
      }
    });
    partition_.CountMerges(static_cast<uint32_t>(keep_gone.size()));
    MergeNeighboursOfPairs(keep_gone);
  }

  // The cluster adjacency after a PML level's merges of disjoint pairs: every list that
  // changes (a kept cluster's, and those of the clusters next to a gone one) is rebuilt
  // from the lists before, with gone ids replaced by their kept ones, in parallel. The
  // counts are those MergeNeighbours gives pair after pair, and the same live clusters are
  // marked dirty; only the order of a list's entries may differ, which no result depends
  // on (a cluster's ODE is its cheapest edge in a total order: cost, then the larger id).
  void MergeNeighboursOfPairs(std::span<const std::pair<uint32_t, uint32_t>> keep_gone) {
    if (kept_of_.size() != n_) {
      kept_of_.assign(n_, detail::kNoCluster);
      gone_of_.assign(n_, detail::kNoCluster);
      rebuild_mark_.assign(n_, 0);
    }
    for (const auto& [keep, gone] : keep_gone) {
      kept_of_[gone] = keep;
      gone_of_[keep] = gone;
    }
    auto kept = [&](uint32_t c) { return kept_of_[c] == detail::kNoCluster ? c : kept_of_[c]; };
    // The lists to rebuild and the dirty clusters, found in parallel blocks of pairs (the
    // marks taken atomically) and joined in block order; the order of either list changes
    // no result in a PML level (each entry is its own cluster's, see UpdateOdesInParallel).
    constexpr size_t kPairBlock = 256;
    const size_t blocks = (keep_gone.size() + kPairBlock - 1) / kPairBlock;
    block_rebuild_.resize(blocks);
    block_dirty_.resize(blocks);
    tbb::parallel_for(size_t{0}, blocks, [&](size_t b) {
      std::vector<uint32_t>& rebuild = block_rebuild_[b];
      std::vector<uint32_t>& dirty = block_dirty_[b];
      rebuild.clear();
      dirty.clear();
      for (size_t i = b * kPairBlock, end = std::min(keep_gone.size(), (b + 1) * kPairBlock);
           i < end; ++i) {
        for (const auto& [c, count] : neighbours_[keep_gone[i].second]) {
          const uint32_t x = kept(c);
          // Its ODE may have been `gone` or `c`.
          if (std::atomic_ref<uint8_t>(dirty_mark_[x]).exchange(1, std::memory_order_relaxed) ==
              0) {
            dirty.push_back(x);
          }
          if (std::atomic_ref<uint8_t>(rebuild_mark_[x]).exchange(1, std::memory_order_relaxed) ==
              0) {
            rebuild.push_back(x);
          }
        }
      }
    });
    rebuild_.clear();
    for (size_t b = 0; b < blocks; ++b) {
      rebuild_.insert(rebuild_.end(), block_rebuild_[b].begin(), block_rebuild_[b].end());
      dirty_.insert(dirty_.end(), block_dirty_[b].begin(), block_dirty_[b].end());
    }
    // Each task writes only its own cluster's list and reads it and its gone cluster's
    // (no gone cluster is rebuilt).
    tbb::parallel_for(tbb::blocked_range<size_t>(0, rebuild_.size(), 256),
                      [&](const tbb::blocked_range<size_t>& range) {
                        std::vector<std::pair<uint32_t, uint32_t>> merged;
                        for (size_t k = range.begin(); k != range.end(); ++k) {
                          const uint32_t x = rebuild_[k];
                          merged.clear();
                          auto add = [&](uint32_t c, uint32_t count) {
                            const uint32_t to = kept(c);
                            if (to == x) return;
                            for (auto& entry : merged) {
                              if (entry.first == to) {
                                entry.second += count;
                                return;
                              }
                            }
                            merged.push_back({to, count});
                          };
                          for (const auto& [c, count] : neighbours_[x]) add(c, count);
                          if (gone_of_[x] != detail::kNoCluster) {
                            for (const auto& [c, count] : neighbours_[gone_of_[x]]) add(c, count);
                          }
                          neighbours_[x].assign(merged.begin(), merged.end());
                        }
                      });
    // The gone lists' memory back in parallel (freeing them one by one was ~2% of a PML
    // run's work on one core).
    tbb::parallel_for(tbb::blocked_range<size_t>(0, keep_gone.size(), 256),
                      [&](const tbb::blocked_range<size_t>& range) {
                        for (size_t i = range.begin(); i != range.end(); ++i) {
                          const auto [keep, gone] = keep_gone[i];
                          std::vector<std::pair<uint32_t, uint32_t>>().swap(neighbours_[gone]);
                          kept_of_[gone] = detail::kNoCluster;
                          gone_of_[keep] = detail::kNoCluster;
                        }
                      });
    for (uint32_t x : rebuild_) rebuild_mark_[x] = 0;
  }

  // Local optimisation around the `region` clusters, from their boundary faces outward.
  void Optimise(std::span<const uint32_t> region, bool parallel_level) {
    CollectBoundaryFaces(region);
    if (vertex_count_guard_.has_value()) {
      const VertexCountGuardWithoutCounts guard{&*vertex_count_guard_};
      OptimiseWith(&guard, parallel_level);
    } else {
      OptimiseWith(guard_.has_value() ? &*guard_ : nullptr, parallel_level);
    }
  }

  // Alg. 3.2 asked without kept counts: a merge relabels a whole cluster at once.
  struct VertexCountGuardWithoutCounts {
    const VertexBoundaryEdgeCountGuard* guard;
    bool CanMove(uint32_t face, uint32_t to, std::span<const uint32_t> labels,
                 std::span<const uint32_t> cluster_sizes) const {
      return guard->CanMoveWithoutCounts(face, to, labels, cluster_sizes);
    }
  };

  template <typename Guard>
  void OptimiseWith(const Guard* guard, bool parallel_level) {
    // Touch (before each move) keeps the clusters' energies from before the level; this
    // runs after the move.
    auto on_move = [&](uint32_t face, uint32_t from, uint32_t to) {
      recorder_.RecordMove(face, from);
      OnFaceMoved(face, from, to);
      ++optimisation_moves_;
    };
    const uint64_t max_moves = 64 * static_cast<uint64_t>(worklist_.size()) + 1024;
    if constexpr (std::is_same_v<Guard, ConnectivityGuard>) {  // the ring guard, or none
      if (options_.optimizer == MultilevelOptions::Optimizer::kEmlo && parallel_level &&
          options_.parallel_optimisation && options_.independent_moves) {
        const uint64_t left = OptimiseInIndependentRounds(guard, max_moves);
        // The rounds stopped paying (few winners): the rest in face order.
        if (left > 0) OptimiseInRounds(guard, left, on_move);
        return;
      }
    }
    if (options_.optimizer == MultilevelOptions::Optimizer::kEmlo && parallel_level &&
        options_.parallel_optimisation) {
      OptimiseInRounds(guard, max_moves, on_move);
    } else if (options_.optimizer == MultilevelOptions::Optimizer::kEmlo) {
      evaluations_ +=
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

  // Section 4.2.2's flags: only clusters whose configuration changed (sums changed, or
  // their ODE partner changed or left) get their ODE recomputed; a neighbour of a changed
  // cluster only compares the one edge that changed, unless its ODE was that edge.
  void UpdateOdes(Engine& engine) {
    for (uint32_t c : recorder_.affected()) MarkDirty(c);
    if (engine.in_parallel_level()) {
      UpdateOdesInParallel(engine);
      return;
    }
    for (uint32_t c : dirty_) {
      if (Alive(c)) engine.RecomputeOde(c);
    }
    for (uint32_t c : recorder_.affected()) {
      if (!Alive(c)) continue;
      for (const auto& [d, count] : neighbours_[c]) {
        if (dirty_mark_[d]) continue;  // recomputed in full above
        if (engine.partner(d) == c) {
          MarkDirty(d);  // its best edge changed: it may no longer be the best
          engine.RecomputeOde(d);
          continue;
        }
        engine.Offer(d, c);
      }
    }
  }
  // The same flags in a PML level, turned around so that each cluster's update is its
  // own (and runs in parallel): a dirty cluster recomputes its ODE in full; a neighbour d
  // of a changed cluster recomputes in full if its ODE was a changed cluster, and
  // otherwise compares its ODE with the edges to the changed clusters. Each is the
  // cheapest edge of d in the same total order (cost, then the larger id) as the push
  // order above gives, so the ODEs are the same.
  void UpdateOdesInParallel(Engine& engine) {
    update_.clear();
    for (uint32_t c : dirty_) {
      if (Alive(c)) update_.push_back(c);
    }
    const size_t full = update_.size();
    for (uint32_t c : recorder_.affected()) affected_mark_[c] = 1;
    for (uint32_t c : recorder_.affected()) {
      if (!Alive(c)) continue;
      for (const auto& [d, count] : neighbours_[c]) {
        if (dirty_mark_[d] || check_mark_[d]) continue;
        check_mark_[d] = 1;
        update_.push_back(d);
      }
    }
    auto update = [&](size_t i) {
      const uint32_t d = update_[i];
      if (i < full) {
        const auto [partner, cost] = engine.FindOde(d);
        engine.AssignOde(d, partner, cost);
        return;
      }
      uint32_t best_partner = engine.partner(d);
      double best_cost = engine.cost(d);
      for (const auto& [c, count] : neighbours_[d]) {
        if (affected_mark_[c] && c == best_partner) {
          const auto [partner, cost] = engine.FindOde(d);
          engine.AssignOde(d, partner, cost);
          return;
        }
      }
      bool changed = false;
      for (const auto& [candidate, count] : neighbours_[d]) {
        if (!affected_mark_[candidate]) continue;
        const double cost = MergeCost(d, candidate);
        if (detail::CheaperDualEdge(cost, candidate, best_cost, best_partner)) {
          best_cost = cost;
          best_partner = candidate;
          changed = true;
        }
      }
      if (changed) engine.AssignOde(d, best_partner, best_cost);
    };
    if (update_.size() < detail::kParallelOdeGrain) {
      for (size_t i = 0; i < update_.size(); ++i) update(i);
    } else {
      tbb::parallel_for(tbb::blocked_range<size_t>(0, update_.size(), 128),
                        [&](const tbb::blocked_range<size_t>& range) {
                          for (size_t i = range.begin(); i != range.end(); ++i) update(i);
                        });
    }
    for (uint32_t c : recorder_.affected()) affected_mark_[c] = 0;
    for (size_t i = full; i < update_.size(); ++i) check_mark_[update_[i]] = 0;
  }

  // Face adjacency reaches every cluster of a component: nothing more to link.
  bool ConnectWhenStuck(Engine& /*engine*/) { return false; }

  void Squash() {
    // The level's end (issue 26 item 7): the exact sums of the clusters that lost a face are
    // summed again from their faces, and the touched clusters' energies taken from the exact
    // sums, so that the level's energy is its labels'. Costs the faces of those clusters.
    const Energy& energy = partition_.energy();
    for (uint32_t c : recorder_.affected()) {
      if (shrunk_mark_[c]) {
        shrunk_mark_[c] = 0;
        typename Energy::Sums sums;
        for (uint32_t f : members_[c]) sums += energy.face_sums(f);
        exact_sums_[c] = sums;
      }
      exact_energy_[c] = members_[c].empty() ? 0.0 : energy.Energy(exact_sums_[c]);
    }
    recorder_.Squash([&](uint32_t c) { return exact_energy_[c]; },
                     [&](uint32_t f) { return partition_.label(f); }, [](uint32_t f) { return f; },
                     detail::TbbBlocks{/*grain=*/1});
  }
  void EndLevel() {
    for (uint32_t c : dirty_) dirty_mark_[c] = 0;
    dirty_.clear();
  }
  void Inspect(size_t level) {
    if (options_.inspect_level) options_.inspect_level(level, partition_.labels());
  }
  LevelRecorder& recorder() { return recorder_; }

 private:
  static std::vector<uint32_t> Identity(uint32_t n) {
    std::vector<uint32_t> ids(n);
    for (uint32_t i = 0; i < n; ++i) ids[i] = i;
    return ids;
  }

  // ---- cluster adjacency: per cluster, (neighbour, number of shared face edges) --------

  // One cluster per face: the clusters' adjacency is the faces'. Each face writes only its
  // own lists, so the faces are taken in parallel blocks of 16,384 (cancellation is checked
  // per block).
  absl::Status BuildClusterAdjacency() {
    tbb::parallel_for(tbb::blocked_range<uint32_t>(0, n_, 16384),
                      [&](const tbb::blocked_range<uint32_t>& range) {
                        if (IsCancelled(options_.cancel)) return;
                        for (uint32_t f = range.begin(); f != range.end(); ++f) {
                          members_[f] = {f};
                          for (FaceId g : adjacency_.neighbours[f]) {
                            // Each face edge is seen from both faces: one side each time;
                            // counts only grow here, so no cluster is marked dirty.
                            if (g.valid() && g.value() != f) AddEdgesOneSide(f, g.value(), 1);
                          }
                        }
                      });
    return CheckCancelled(options_.cancel, "ML set-up");
  }

  // The cluster adjacency after `gone` merged into `keep`.
  void MergeNeighbours(uint32_t keep, uint32_t gone) {
    for (const auto& [c, count] : neighbours_[gone]) {
      MarkDirty(c);  // its ODE may have been `gone`
      AddEdgesOneSide(c, gone, -static_cast<int32_t>(count));
      if (c == keep) continue;
      AddEdgesOneSide(keep, c, static_cast<int32_t>(count));
      AddEdgesOneSide(c, keep, static_cast<int32_t>(count));
    }
    std::vector<std::pair<uint32_t, uint32_t>>().swap(neighbours_[gone]);
  }

  void AddEdgesOneSide(uint32_t x, uint32_t z, int32_t delta) {
    AddEdgesOneSide(x, z, delta, [&](uint32_t c) { MarkDirty(c); });
  }
  // The same, with `mark_dirty` called instead of MarkDirty.
  template <typename MarkDirtyFn>
  void AddEdgesOneSide(uint32_t x, uint32_t z, int32_t delta, const MarkDirtyFn& mark_dirty) {
    auto& list = neighbours_[x];
    for (size_t i = 0; i < list.size(); ++i) {
      if (list[i].first == z) {
        list[i].second += delta;
        if (list[i].second == 0) {
          list[i] = list.back();
          list.pop_back();
          mark_dirty(x);  // x's ODE may have been the neighbour it no longer touches
        }
        return;
      }
    }
    if (delta > 0) list.push_back({z, static_cast<uint32_t>(delta)});
  }

  // Face f moved from y to x: each of its edges now borders x instead of y.
  void OnFaceMoved(uint32_t f, uint32_t y, uint32_t x) {
    OnFaceMoved(f, y, x, [&](uint32_t c) { MarkDirty(c); });
  }
  // The same, with `mark_dirty` called instead of MarkDirty. Writes only the lists of y,
  // x and the clusters of f's edge neighbours, the members of y and x, and the positions
  // of f and of a face of y.
  template <typename MarkDirtyFn>
  void OnFaceMoved(uint32_t f, uint32_t y, uint32_t x, const MarkDirtyFn& mark_dirty) {
    // The exact sums (Squash): x gains f's sums; y's are summed again at the level's end.
    exact_sums_[x] += partition_.energy().face_sums(f);
    shrunk_mark_[y] = 1;
    for (FaceId g : adjacency_.neighbours[f]) {
      if (!g.valid()) continue;
      const uint32_t z = partition_.label(g.value());
      if (y != z) {
        AddEdgesOneSide(y, z, -1, mark_dirty);
        AddEdgesOneSide(z, y, -1, mark_dirty);
      }
      if (x != z) {
        AddEdgesOneSide(x, z, 1, mark_dirty);
        AddEdgesOneSide(z, x, 1, mark_dirty);
      }
    }
    detail::MoveMember(members_, position_, f, y, x);
  }

  void Touch(uint32_t cluster) {
    recorder_.Touch(cluster, [&](uint32_t c) { return exact_energy_[c]; });
  }
  // A merge of `gone` into `keep` in the exact sums (Squash); writes only the two clusters.
  void MergeExactSums(uint32_t keep, uint32_t gone) {
    exact_sums_[keep] += exact_sums_[gone];
    exact_sums_[gone] = typename Energy::Sums();
    shrunk_mark_[keep] |= shrunk_mark_[gone];
    shrunk_mark_[gone] = 0;
  }
  void MarkDirty(uint32_t c) {
    if (dirty_mark_[c]) return;
    dirty_mark_[c] = 1;
    dirty_.push_back(c);
  }

  bool OnBoundary(uint32_t f, uint32_t c) const {
    for (FaceId g : adjacency_.neighbours[f]) {
      if (g.valid() && partition_.label(g.value()) != c) return true;
    }
    return false;
  }
  // worklist_: the boundary faces of the `region` clusters, cluster by cluster, each
  // cluster's in member order; counted and filled in parallel over the clusters where
  // there are many (the same list either way).
  void CollectBoundaryFaces(std::span<const uint32_t> region) {
    worklist_.clear();
    if (region.size() < detail::kParallelOdeGrain) {
      for (uint32_t c : region) {
        for (uint32_t f : members_[c]) {
          if (OnBoundary(f, c)) worklist_.push_back(f);
        }
      }
      return;
    }
    boundary_offset_.assign(region.size() + 1, 0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, region.size(), 64), [&](const auto& range) {
      for (size_t i = range.begin(); i != range.end(); ++i) {
        uint32_t count = 0;
        for (uint32_t f : members_[region[i]]) count += OnBoundary(f, region[i]) ? 1 : 0;
        boundary_offset_[i + 1] = count;
      }
    });
    for (size_t i = 0; i < region.size(); ++i) boundary_offset_[i + 1] += boundary_offset_[i];
    worklist_.resize(boundary_offset_.back());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, region.size(), 64), [&](const auto& range) {
      for (size_t i = range.begin(); i != range.end(); ++i) {
        size_t at = boundary_offset_[i];
        for (uint32_t f : members_[region[i]]) {
          if (OnBoundary(f, region[i])) worklist_[at++] = f;
        }
      }
    });
  }

  // The best move of face f itself, from the sums as they are: the neighbouring cluster
  // whose joining lowers E(own) + E(to) the most (eqs. 3.33-3.35), and by how much; none
  // (kNoCluster) where no move lowers it by more than rounding, or f is its cluster's last
  // face. Reads only; safe in parallel while nothing moves.
  std::pair<uint32_t, double> BestOwnMove(uint32_t f) const {
    const Energy& energy = partition_.energy();
    const uint32_t own = partition_.label(f);
    if (partition_.size(own) <= 1) return {detail::kNoCluster, 0.0};
    typename Energy::Sums own_without = partition_.sums(own);
    own_without -= energy.face_sums(f);
    const double own_after = energy.Energy(own_without);
    uint32_t best_to = detail::kNoCluster;
    double best_gain = 0;
    for (FaceId g : adjacency_.neighbours[f]) {
      if (!g.valid()) continue;
      const uint32_t to = partition_.label(g.value());
      if (to == own || to == best_to) continue;
      const double keep = partition_.cluster_energy(own) + partition_.cluster_energy(to);
      const double after = own_after + energy.Energy(partition_.sums(to) + energy.face_sums(f));
      const double gain = keep - after;
      // Rounding in the sums is ~1e-16 relative; demand a real improvement.
      if (gain > kRelativeImprovement * keep && gain > best_gain) {
        best_gain = gain;
        best_to = to;
      }
    }
    return {best_to, best_gain};
  }

  // The first list of the parallel rounds: worklist_ (the region's boundary faces) with the
  // faces across their boundary edges (EMLO compares both sides of each edge), sorted and
  // without repeats.
  void AddFacesAcrossBoundaries() {
    std::vector<uint32_t>& list = worklist_;
    const size_t first = list.size();
    for (size_t i = 0; i < first; ++i) {
      for (FaceId g : adjacency_.neighbours[list[i]]) {
        if (g.valid() && partition_.label(g.value()) != partition_.label(list[i])) {
          list.push_back(g.value());
        }
      }
    }
    tbb::parallel_sort(list.begin(), list.end());  // integers: the same order on any thread count
    list.erase(std::unique(list.begin(), list.end()), list.end());
  }

  // MultilevelOptions::parallel_optimisation: rounds of "every face of the list finds its
  // best move in parallel, then the moves are checked again and applied in face order".
  template <typename Guard, typename OnMove>
  void OptimiseInRounds(const Guard* guard, uint64_t max_moves, OnMove& on_move) {
    AddFacesAcrossBoundaries();
    std::vector<uint32_t>& list = worklist_;
    std::vector<uint32_t> target, next;
    std::vector<uint8_t> allowed;
    // The ring test's answers from the parallel pass are kept (see below).
    constexpr bool kGuardAnswerKept = std::is_same_v<Guard, ConnectivityGuard>;
    uint64_t moves = 0;
    while (!list.empty() && moves < max_moves && !IsCancelled(options_.cancel)) {
      target.resize(list.size());
      allowed.resize(list.size());
      // Each face's move and the guard's answer for it, from the round's state.
      tbb::parallel_for(tbb::blocked_range<size_t>(0, list.size(), 256),
                        [&](const tbb::blocked_range<size_t>& range) {
                          for (size_t i = range.begin(); i != range.end(); ++i) {
                            target[i] = BestOwnMove(list[i]).first;
                            allowed[i] = target[i] != detail::kNoCluster &&
                                         (!kGuardAnswerKept || guard == nullptr ||
                                          guard->CanMove(list[i], target[i], partition_.labels(),
                                                         partition_.sizes()));
                          }
                        });
      evaluations_ += list.size();
      next.clear();
      if constexpr (kGuardAnswerKept) {
        if (ApplyRoundInSteps(guard, list, target, allowed, max_moves - moves, next, moves)) {
          tbb::parallel_sort(next.begin(), next.end());
          next.erase(std::unique(next.begin(), next.end()), next.end());
          list.swap(next);
          continue;
        }
      }
      for (size_t i = 0; i < list.size() && moves < max_moves; ++i) {
        if (target[i] == detail::kNoCluster) continue;
        const uint32_t f = list[i];
        // Earlier moves of this round may have changed the sums: decide again where a
        // move touched f's cluster or a neighbour's (a neighbour that moved touched both
        // its clusters); elsewhere the decision stands as found.
        bool stale = round_mark_[partition_.label(f)] != 0;
        for (FaceId g : adjacency_.neighbours[f]) {
          stale = stale || (g.valid() && round_mark_[partition_.label(g.value())] != 0);
        }
        // Where the decision stands, so does the ring test's answer: a face around f that
        // moved changed the ring's runs of f's cluster or of the target only by touching one
        // of them, which makes f stale; and f's cluster kept its size. (Alg. 3.2's counts
        // also read boundaries between other clusters: asked here every time.)
        const uint32_t to = stale ? BestOwnMove(f).first : target[i];
        if (to == detail::kNoCluster) continue;
        if (kGuardAnswerKept && !stale && !allowed[i]) continue;
        if ((stale || !kGuardAnswerKept) && guard != nullptr &&
            !guard->CanMove(f, to, partition_.labels(), partition_.sizes())) {
          continue;
        }
        const uint32_t from = partition_.label(f);
        Touch(from);
        Touch(to);
        partition_.Move(f, to);
        on_move(f, from, to);
        ++moves;
        for (uint32_t c : {from, to}) {
          if (!round_mark_[c]) {
            round_mark_[c] = 1;
            round_marked_.push_back(c);
          }
        }
        next.push_back(f);
        for (FaceId g : adjacency_.neighbours[f]) {
          if (g.valid()) next.push_back(g.value());
        }
      }
      for (uint32_t c : round_marked_) round_mark_[c] = 0;
      round_marked_.clear();
      tbb::parallel_sort(next.begin(), next.end());
      next.erase(std::unique(next.begin(), next.end()), next.end());
      list.swap(next);
    }
  }

  // The face-order loop of a round of OptimiseInRounds (ring guard or none), run in
  // parallel steps with the same result (ours; BENCHMARKS.md, "The face-order rounds in
  // parallel steps"). Candidate j (the j-th face of the round's list with a move) reads
  // the clusters of its face and of the faces around it (edge neighbours and ring): the
  // stale test, the new decision and the ring test of a stale face read nothing else, and
  // its move writes only its face's cluster and the target, one of those. Each cluster
  // keeps the list, in list order, of the candidates that read it; a candidate runs once
  // it heads the lists of all its clusters, so every earlier candidate that reads one of
  // them has run and no later one has: it sees the state the loop in list order gives it.
  // A step runs all such candidates in parallel (they read pairwise disjoint clusters);
  // then, where a move took a face from A to B, each open candidate around that face now
  // reads B too and joins B's list after the mover (B is the mover's alone in the step);
  // then the movers leave their lists' heads. The round's moves, labels, sums and cluster
  // lists are the loop's; the shared lists (the recorder's, the dirty clusters) are filled
  // afterwards in candidate order. Once a step would run fewer than kStepsMinFrontier
  // candidates, the rest run in list order. Nothing depends on the thread count (the steps
  // are fixed by the lists). Assumes "face g is around face f" is symmetric (edge
  // neighbours; rings of a manifold mesh, which ValidateMesh ensures). False (nothing done)
  // where the round has fewer than kStepsFrom candidates or max_moves could end it early:
  // the loop runs it.
  // next = each of `count` moved faces (face_of(k)) followed by its edge neighbours, at
  // offsets counted in parallel (the same list on any thread count), and `extra` entries
  // after them for the caller to fill.
  template <typename FaceOf>
  void ListMovedAndNeighbours(size_t count, const FaceOf& face_of, size_t extra,
                              std::vector<size_t>& offset, std::vector<uint32_t>& next) const {
    offset.assign(count + 1, 0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, count, 1024),
                      [&](const tbb::blocked_range<size_t>& range) {
                        for (size_t k = range.begin(); k != range.end(); ++k) {
                          size_t faces = 1;
                          for (FaceId g : adjacency_.neighbours[face_of(k)]) {
                            faces += g.valid() ? 1 : 0;
                          }
                          offset[k + 1] = faces;
                        }
                      });
    for (size_t k = 0; k < count; ++k) offset[k + 1] += offset[k];
    next.resize(offset.back() + extra);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, count, 1024),
                      [&](const tbb::blocked_range<size_t>& range) {
                        for (size_t k = range.begin(); k != range.end(); ++k) {
                          const uint32_t f = face_of(k);
                          size_t at = offset[k];
                          next[at++] = f;
                          for (FaceId g : adjacency_.neighbours[f]) {
                            if (g.valid()) next[at++] = g.value();
                          }
                        }
                      });
  }

  // Whether ApplyRoundInSteps runs (detail::face_order_steps; either way the same levels).
  static bool FaceOrderStepsOn() {
    switch (detail::face_order_steps.load(std::memory_order_relaxed)) {
      case detail::FaceOrderSteps::kAlways:
        return true;
      case detail::FaceOrderSteps::kNever:
        return false;
      case detail::FaceOrderSteps::kFromFourThreads:
        break;
    }
    return tbb::this_task_arena::max_concurrency() >= detail::kFaceOrderStepsFromThreads;
  }
  bool ApplyRoundInSteps(const ConnectivityGuard* guard, std::span<const uint32_t> list,
                         std::span<const uint32_t> target, std::span<const uint8_t> allowed,
                         uint64_t moves_left, std::vector<uint32_t>& next, uint64_t& moves) {
    std::vector<uint32_t>& candidates = step_candidates_;
    detail::CompactIndices(
        list.size(), [&](size_t i) { return target[i] != detail::kNoCluster; }, candidates);
    const size_t m = candidates.size();
    if (m < kStepsFrom || m > moves_left || !FaceOrderStepsOn()) {
      return false;
    }
    // The clusters face f reads (duplicates allowed).
    auto for_each_read = [&](uint32_t f, const auto& visit) {
      visit(partition_.label(f));
      for (FaceId g : adjacency_.neighbours[f]) {
        if (g.valid()) visit(partition_.label(g.value()));
      }
      if (guard != nullptr) {
        for (uint32_t g : guard->Ring(f)) {
          if (g != ConnectivityGuard::kGap) visit(partition_.label(g));
        }
      }
    };
    auto energy_of = [&](uint32_t c) { return exact_energy_[c]; };
    step_moves_.resize(m);
    // The loop's body for candidate j, its entries in the shared lists kept in its record.
    auto body = [&](uint32_t j) {
      UnlistedMove& move = step_moves_[j];
      move.applied = false;
      step_done_[j] = 1;
      const uint32_t i = candidates[j], f = list[i];
      bool stale = round_mark_[partition_.label(f)] != 0;
      for (FaceId g : adjacency_.neighbours[f]) {
        stale = stale || (g.valid() && round_mark_[partition_.label(g.value())] != 0);
      }
      const uint32_t to = stale ? BestOwnMove(f).first : target[i];
      if (to == detail::kNoCluster) return;
      if (!stale && !allowed[i]) return;
      if (stale && guard != nullptr &&
          !guard->CanMove(f, to, partition_.labels(), partition_.sizes())) {
        return;
      }
      ApplyMoveUnlisted(f, to, energy_of, move);
      move.applied = true;
    };
    // Per candidate its clusters (the set grows where a move brings a new cluster next to
    // its face: room for one per face around it, as each moves at most once per round).
    std::vector<uint32_t>& set_offset = step_set_offset_;
    set_offset.assign(m + 1, 0);
    if (step_set_size_.size() < m) step_set_size_ = std::vector<std::atomic<uint32_t>>(m);
    tbb::parallel_for(
        tbb::blocked_range<size_t>(0, m, 256), [&](const tbb::blocked_range<size_t>& range) {
          std::vector<uint32_t> seen;
          for (size_t j = range.begin(); j != range.end(); ++j) {
            const uint32_t f = list[candidates[j]];
            seen.clear();
            uint32_t faces = 0;
            for_each_read(f, [&](uint32_t c) {
              ++faces;
              if (std::find(seen.begin(), seen.end(), c) == seen.end()) {
                seen.push_back(c);
              }
            });
            set_offset[j + 1] = static_cast<uint32_t>(seen.size()) + faces;
            step_set_size_[j].store(static_cast<uint32_t>(seen.size()), std::memory_order_relaxed);
          }
        });
    for (size_t j = 0; j < m; ++j) set_offset[j + 1] += set_offset[j];
    step_set_.resize(set_offset[m]);
    if (step_of_face_.size() != n_) {
      step_of_face_.assign(n_, detail::kNoCluster);
      step_queue_.resize(n_);
      step_head_.assign(n_, 0);
    }
    tbb::parallel_for(
        tbb::blocked_range<size_t>(0, m, 256), [&](const tbb::blocked_range<size_t>& range) {
          for (size_t j = range.begin(); j != range.end(); ++j) {
            const uint32_t f = list[candidates[j]];
            step_of_face_[f] = static_cast<uint32_t>(j);
            uint32_t at = set_offset[j];
            const uint32_t begin = at;
            for_each_read(f, [&](uint32_t c) {
              if (std::find(&step_set_[begin], &step_set_[at], c) == &step_set_[at]) {
                step_set_[at++] = c;
              }
            });
            std::fill(&step_set_[at], &step_set_[set_offset[j + 1]], detail::kNoCluster);
          }
        });
    // Per cluster, the candidates that read it, in list order (the first is its head).
    step_clusters_.clear();
    for (size_t j = 0; j < m; ++j) {
      for (uint32_t at = set_offset[j], end = at + step_set_size_[j].load(); at < end; ++at) {
        std::vector<uint32_t>& queue = step_queue_[step_set_[at]];
        if (queue.empty()) step_clusters_.push_back(step_set_[at]);
        queue.push_back(static_cast<uint32_t>(j));
      }
    }
    // Per candidate, the number of its clusters it is not the head of.
    if (step_pending_.size() < m) step_pending_ = std::vector<std::atomic<uint32_t>>(m);
    step_done_.assign(m, 0);
    tbb::parallel_for(
        tbb::blocked_range<size_t>(0, m, 256), [&](const tbb::blocked_range<size_t>& range) {
          for (size_t j = range.begin(); j != range.end(); ++j) {
            uint32_t pending = 0;
            for (uint32_t at = set_offset[j],
                          end = at + step_set_size_[j].load(std::memory_order_relaxed);
                 at < end; ++at) {
              pending += step_queue_[step_set_[at]].front() != j ? 1 : 0;
            }
            step_pending_[j].store(pending, std::memory_order_relaxed);
          }
        });
    detail::CompactIndices(
        m, [&](size_t j) { return step_pending_[j].load(std::memory_order_relaxed) == 0; },
        step_frontier_);
    uint64_t steps = 0;
    size_t in_steps = 0;
    // The faces whose candidates read the label of face h (the relation is symmetric).
    auto for_each_around = [&](uint32_t h, const auto& visit) {
      for (FaceId g : adjacency_.neighbours[h]) {
        if (g.valid()) visit(g.value());
      }
      if (guard != nullptr) {
        for (uint32_t g : guard->Ring(h)) {
          if (g != ConnectivityGuard::kGap) visit(g);
        }
      }
    };
    while (step_frontier_.size() >= kStepsMinFrontier) {
      ++steps;
      const size_t width = step_frontier_.size();
      in_steps += width;
      const tbb::blocked_range<size_t> all(0, width, 32);
      tbb::parallel_for(all, [&](const tbb::blocked_range<size_t>& range) {
        for (size_t r = range.begin(); r != range.end(); ++r) body(step_frontier_[r]);
      });
      // A move from A to B: a candidate whose face is around the moved face now reads B.
      // It joins B's list (B is the mover's alone in this step) after the mover.
      tbb::parallel_for(all, [&](const tbb::blocked_range<size_t>& range) {
        for (size_t r = range.begin(); r != range.end(); ++r) {
          const uint32_t j = step_frontier_[r];
          const UnlistedMove& move = step_moves_[j];
          if (!move.applied) continue;
          std::vector<uint32_t>& queue = step_queue_[move.to];
          for_each_around(list[candidates[j]], [&](uint32_t g) {
            const uint32_t q = step_of_face_[g];
            if (q == detail::kNoCluster || step_done_[q]) return;
            const uint32_t size = step_set_size_[q].load(std::memory_order_acquire);
            for (uint32_t at = set_offset[q]; at < set_offset[q] + size; ++at) {
              if (std::atomic_ref<uint32_t>(step_set_[at]).load(std::memory_order_relaxed) ==
                  move.to) {
                return;
              }
            }
            // Another mover of this step may add another cluster to q's set at once.
            const uint32_t at = set_offset[q] + step_set_size_[q].fetch_add(1);
            std::atomic_ref<uint32_t>(step_set_[at]).store(move.to, std::memory_order_relaxed);
            queue.insert(std::upper_bound(queue.begin() + step_head_[move.to], queue.end(), q), q);
            step_pending_[q].fetch_add(1, std::memory_order_relaxed);
          });
        }
      });
      // Each mover leaves the head of its clusters' lists; a candidate that is now the
      // head of all of its is in the next step.
      step_next_offset_.assign(width + 1, 0);
      for (size_t r = 0; r < width; ++r) {
        step_next_offset_[r + 1] = step_next_offset_[r] + step_set_size_[step_frontier_[r]].load(
                                                              std::memory_order_relaxed);
      }
      step_next_.assign(step_next_offset_[width], detail::kNoCluster);
      tbb::parallel_for(all, [&](const tbb::blocked_range<size_t>& range) {
        for (size_t r = range.begin(); r != range.end(); ++r) {
          const uint32_t j = step_frontier_[r];
          uint32_t out = step_next_offset_[r];
          for (uint32_t at = set_offset[j],
                        end = at + step_set_size_[j].load(std::memory_order_relaxed);
               at < end; ++at) {
            const uint32_t c = step_set_[at];
            const std::vector<uint32_t>& queue = step_queue_[c];
            const uint32_t head = ++step_head_[c];
            if (head < queue.size() &&
                step_pending_[queue[head]].fetch_sub(1, std::memory_order_acq_rel) == 1) {
              step_next_[out++] = queue[head];
            }
          }
        }
      });
      detail::CompactIndices(
          step_next_.size(), [&](size_t k) { return step_next_[k] != detail::kNoCluster; },
          step_frontier_);
      for (uint32_t& k : step_frontier_) k = step_next_[k];
      tbb::parallel_sort(step_frontier_.begin(), step_frontier_.end());
    }
    // The rest in list order.
    for (size_t j = 0; j < m; ++j) {
      if (!step_done_[j]) body(static_cast<uint32_t>(j));
    }
    for (uint32_t c : step_clusters_) {
      step_queue_[c].clear();
      step_head_[c] = 0;
    }
    tbb::parallel_for(tbb::blocked_range<size_t>(0, m, 1024),
                      [&](const tbb::blocked_range<size_t>& range) {
                        for (size_t j = range.begin(); j != range.end(); ++j) {
                          step_of_face_[list[candidates[j]]] = detail::kNoCluster;
                        }
                      });
    // The shared lists in candidate order, as the loop fills them.
    detail::CompactIndices(
        m, [&](size_t j) { return step_moves_[j].applied; }, step_applied_);
    for (uint32_t j : step_applied_) {
      const UnlistedMove& move = step_moves_[j];
      ListMove(move, list[candidates[j]]);
      round_mark_[move.from] = round_mark_[move.to] = 0;
    }
    moves += step_applied_.size();
    optimisation_moves_ += step_applied_.size();
    detail::FaceOrderStepsCounters& counters = detail::face_order_steps_counters;
    counters.rounds.fetch_add(1, std::memory_order_relaxed);
    counters.steps.fetch_add(steps, std::memory_order_relaxed);
    counters.candidates.fetch_add(m, std::memory_order_relaxed);
    counters.in_steps.fetch_add(in_steps, std::memory_order_relaxed);
    counters.moves.fetch_add(step_applied_.size(), std::memory_order_relaxed);
    // The next list: each moved face and its edge neighbours (sorted by the caller).
    ListMovedAndNeighbours(
        step_applied_.size(), [&](size_t a) { return list[candidates[step_applied_[a]]]; }, 0,
        step_offset_, next);
    return true;
  }

  // The winners of an independent round (apply[j] = 1; 0: the guard refused the move; 2:
  // it waits for the next round), the first maximal set of candidates, in list order, that
  // read pairwise disjoint clusters and that the guard allows: a candidate wins where no
  // earlier winner reads a cluster it reads. Found in steps, in parallel: the candidates
  // still open that are the first open one on every cluster they read win (their guard
  // answers from the round's state), their clusters are taken, the open candidates that
  // read a taken cluster wait, and the rest go to the next step. Each step's winners are
  // those of the one-by-one scan in list order, so the set does not depend on the thread
  // count. (The former rule let a candidate wait behind an earlier one that itself waited:
  // with clusters of hundreds of faces about one candidate in 500 won per round.)
  template <typename ForEachRead>
  void SelectIndependentMoves(const ConnectivityGuard* guard, std::span<const uint32_t> list,
                              std::span<const uint32_t> target,
                              std::span<const uint32_t> candidates,
                              const ForEachRead& for_each_read, std::vector<uint8_t>& apply) {
    apply.assign(candidates.size(), 2);
    open_.resize(candidates.size());
    for (size_t j = 0; j < candidates.size(); ++j) open_[j] = static_cast<uint32_t>(j);
    blocked_.assign(candidates.size(), 0);
    while (!open_.empty()) {
      const tbb::blocked_range<size_t> all(0, open_.size(), 256);
      // Reserve: every cluster not taken keeps the first open candidate that reads it; a
      // candidate that reads a taken cluster waits (and reserves nothing).
      tbb::parallel_for(all, [&](const tbb::blocked_range<size_t>& range) {
        for (size_t k = range.begin(); k != range.end(); ++k) {
          const uint32_t j = open_[k], f = list[candidates[j]];
          bool blocked = false;
          for_each_read(f, [&](uint32_t c) {
            blocked = blocked || reserve_[c].load(std::memory_order_relaxed) == kTaken;
          });
          blocked_[j] = blocked ? 1 : 0;
          if (blocked) continue;
          for_each_read(f, [&](uint32_t c) {
            uint32_t seen = reserve_[c].load(std::memory_order_relaxed);
            while (j < seen &&
                   !reserve_[c].compare_exchange_weak(seen, j, std::memory_order_relaxed)) {
            }
          });
        }
      });
      // The first everywhere win where the guard allows their move (their rings are
      // disjoint from the other winners' moves, so the answer holds after those apply).
      tbb::parallel_for(all, [&](const tbb::blocked_range<size_t>& range) {
        for (size_t k = range.begin(); k != range.end(); ++k) {
          const uint32_t j = open_[k];
          if (blocked_[j]) continue;
          const uint32_t i = candidates[j];
          bool first_everywhere = true;
          for_each_read(list[i], [&](uint32_t c) {
            first_everywhere = first_everywhere && reserve_[c].load(std::memory_order_relaxed) == j;
          });
          if (!first_everywhere) continue;
          apply[j] = guard == nullptr || guard->CanMove(list[i], target[i], partition_.labels(),
                                                        partition_.sizes())
                         ? 1
                         : 0;
        }
      });
      tbb::parallel_for(all, [&](const tbb::blocked_range<size_t>& range) {
        for (size_t k = range.begin(); k != range.end(); ++k) {
          const uint32_t j = open_[k];
          if (blocked_[j]) continue;
          for_each_read(list[candidates[j]], [&](uint32_t c) {
            reserve_[c].store(kUnreserved, std::memory_order_relaxed);
          });
        }
      });
      tbb::parallel_for(all, [&](const tbb::blocked_range<size_t>& range) {
        for (size_t k = range.begin(); k != range.end(); ++k) {
          const uint32_t j = open_[k];
          if (blocked_[j] || apply[j] != 1) continue;
          for_each_read(list[candidates[j]],
                        [&](uint32_t c) { reserve_[c].store(kTaken, std::memory_order_relaxed); });
        }
      });
      // Still open: neither blocked nor decided.
      detail::CompactIndices(
          open_.size(), [&](size_t k) { return !blocked_[open_[k]] && apply[open_[k]] == 2; },
          still_open_);
      for (uint32_t& k : still_open_) k = open_[k];
      open_.swap(still_open_);
    }
    // The taken clusters back to unreserved (the labels are still the round's).
    tbb::parallel_for(tbb::blocked_range<size_t>(0, candidates.size(), 256),
                      [&](const tbb::blocked_range<size_t>& range) {
                        for (size_t j = range.begin(); j != range.end(); ++j) {
                          if (apply[j] != 1) continue;
                          for_each_read(list[candidates[j]], [&](uint32_t c) {
                            reserve_[c].store(kUnreserved, std::memory_order_relaxed);
                          });
                        }
                      });
  }

  // MultilevelOptions::independent_moves (ours): rounds of "every face of the list finds
  // its best move in parallel; a set of moves that read pairwise disjoint clusters is
  // checked by the guard and applied in parallel; the others wait for the next round".
  // Face f reads the clusters of the faces around it (its ring, which holds its edge
  // neighbours): its own cluster and every target it compares, and every label the guard
  // reads. The winners (SelectIndependentMoves) read and write pairwise disjoint clusters:
  // each one's decision and guard answer from the round's state hold after the others
  // apply, and each lowers the energy. A cluster takes part in one move per round, so a
  // level whose moves crowd on few clusters would need a round per move: once a round of at
  // least kFewWinnersFrom candidates has fewer than one winner in kFewWinnersRatio, nothing
  // of it is applied and the rest of the level goes to the face-order rounds
  // (OptimiseInRounds), with the moves left of max_moves as the return value (0: done
  // here). Without that, the hand-over level of an 832k-face mesh took 4,043 rounds over
  // 38.9M list entries (BENCHMARKS.md, "Why --parallel-optimisation independent did not finish").
  // Which moves win and when the rounds hand over do not depend on the thread count.
  uint64_t OptimiseInIndependentRounds(const ConnectivityGuard* guard, uint64_t max_moves) {
    AddFacesAcrossBoundaries();
    std::vector<uint32_t>& list = worklist_;
    if (kept_target_.size() != n_) kept_target_.assign(n_, kUndecided);
    if (reserve_.size() != n_) {
      reserve_ = std::vector<std::atomic<uint32_t>>(n_);
      for (auto& r : reserve_) r.store(kUnreserved, std::memory_order_relaxed);
    }
    // The clusters f reads: its own and those of the faces around it (duplicates allowed).
    auto for_each_read = [&](uint32_t f, const auto& visit) {
      visit(partition_.label(f));
      if (guard != nullptr) {
        for (uint32_t g : guard->Ring(f)) {
          if (g != ConnectivityGuard::kGap) visit(partition_.label(g));
        }
      } else {
        for (FaceId g : adjacency_.neighbours[f]) {
          if (g.valid()) visit(partition_.label(g.value()));
        }
      }
    };
    std::vector<uint32_t> target, candidates, winners, waiting, next;
    std::vector<uint8_t> apply;
    // A winner's move, as applied: its clusters and what the shared lists get from it.
    std::vector<UnlistedMove> applied;
    std::vector<size_t> next_offset;
    uint64_t moves = 0;
    while (!list.empty() && moves < max_moves && !IsCancelled(options_.cancel)) {
      target.resize(list.size());
      tbb::parallel_for(tbb::blocked_range<size_t>(0, list.size(), 256),
                        [&](const tbb::blocked_range<size_t>& range) {
                          for (size_t i = range.begin(); i != range.end(); ++i) {
                            uint32_t& kept = kept_target_[list[i]];
                            target[i] = kept != kUndecided ? kept : BestOwnMove(list[i]).first;
                            kept = kUndecided;
                          }
                        });
      evaluations_ += list.size();
      detail::CompactIndices(
          list.size(), [&](size_t i) { return target[i] != detail::kNoCluster; }, candidates);
      SelectIndependentMoves(guard, list, target, candidates, for_each_read, apply);
      // The winners apply in parallel (each writes only its own clusters and faces); what
      // goes to shared lists (the recorder's, the dirty clusters) is kept per move and
      // listed after, in candidate order: the same as applying them one by one in order.
      detail::CompactIndices(
          candidates.size(), [&](size_t j) { return apply[j] == 1; }, winners);
      if (winners.size() > max_moves - moves) winners.resize(max_moves - moves);
      if (candidates.size() >= kFewWinnersFrom &&
          winners.size() * kFewWinnersRatio < candidates.size()) {
        for (uint32_t f : list) kept_target_[f] = kUndecided;
        return max_moves - moves;
      }
      moves += winners.size();
      applied.resize(winners.size());
      auto energy_of = [&](uint32_t c) { return exact_energy_[c]; };
      auto apply_one = [&](size_t w) {
        const uint32_t i = candidates[winners[w]];
        ApplyMoveUnlisted(list[i], target[i], energy_of, applied[w]);
      };
      if (winners.size() < 64) {
        for (size_t w = 0; w < winners.size(); ++w) apply_one(w);
      } else {
        tbb::parallel_for(tbb::blocked_range<size_t>(0, winners.size(), 32),
                          [&](const tbb::blocked_range<size_t>& range) {
                            for (size_t w = range.begin(); w != range.end(); ++w) apply_one(w);
                          });
      }
      for (size_t w = 0; w < winners.size(); ++w) {
        ListMove(applied[w], list[candidates[winners[w]]]);
      }
      optimisation_moves_ += winners.size();
      // The next list: each moved face and its edge neighbours (at offsets counted per
      // move), and the faces that waited.
      detail::CompactIndices(
          candidates.size(), [&](size_t j) { return apply[j] == 2; }, waiting);
      // A face that waited keeps its move for the next round where no winner wrote a
      // cluster its decision read (its own and its edge neighbours'): BestOwnMove would
      // find the same.
      tbb::parallel_for(tbb::blocked_range<size_t>(0, waiting.size(), 1024),
                        [&](const tbb::blocked_range<size_t>& range) {
                          for (size_t k = range.begin(); k != range.end(); ++k) {
                            const uint32_t i = candidates[waiting[k]], f = list[i];
                            bool stale = round_mark_[partition_.label(f)] != 0;
                            for (FaceId g : adjacency_.neighbours[f]) {
                              stale = stale ||
                                      (g.valid() && round_mark_[partition_.label(g.value())] != 0);
                            }
                            if (!stale) kept_target_[f] = target[i];
                          }
                        });
      for (const UnlistedMove& move : applied) round_mark_[move.from] = round_mark_[move.to] = 0;
      ListMovedAndNeighbours(
          winners.size(), [&](size_t w) { return list[candidates[winners[w]]]; }, waiting.size(),
          next_offset, next);
      for (size_t k = 0; k < waiting.size(); ++k) {
        next[next_offset.back() + k] = list[candidates[waiting[k]]];
      }
      tbb::parallel_sort(next.begin(), next.end());
      next.erase(std::unique(next.begin(), next.end()), next.end());
      list.swap(next);
    }
    for (uint32_t f : list) kept_target_[f] = kUndecided;  // stopped early: none kept
    return 0;
  }

  // Local boundary-based optimisation: sweeps over the worklist with the touched
  // clusters' proxies fixed per sweep; the faces that moved put their neighbours on the
  // next sweep's list. At most a few sweeps per level.
  template <typename Guard, typename OnMove>
  void OptimiseBoundaryBased(const Guard* guard, OnMove& on_move) {
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
      const auto label = [this](uint32_t face) { return partition_.label(face); };
      for (uint32_t f : worklist_) {
        // Alg. 5.1's decide rule, the sweeps' own (boundary_based.h), on the live labels.
        const uint32_t target = boundary_based::DecideBoundaryMoveWith(partition_.energy(),
                                                                       adjacency_, f, label, proxy);
        if (target == boundary_based::kNoMove) continue;
        const uint32_t own = partition_.label(f);
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

  const Adjacency& adjacency_;
  const MultilevelOptions& options_;
  const TriangleMesh& mesh_;
  const MeshProblem& problem_;
  std::optional<ConnectivityGuard> guard_;  // with an optimiser and options.connectivity_guard
  // Instead of guard_, with options.guard == kVertexBoundaryEdgeCount.
  std::optional<VertexBoundaryEdgeCountGuard> vertex_count_guard_;
  const uint32_t n_;
  Partition<Energy> partition_;
  // What the levels report (issue 26 item 7): per cluster the sums of its faces and their
  // energy as of the last level's end. partition_'s sums decide the merges and moves, as
  // they always did; but a face's sums leave them by subtraction, which loses what it cancels
  // (core/cluster/partition.h), so the reported energies come from these sums instead, which
  // only ever add, and which a cluster that lost a face (shrunk_mark_) has summed again from
  // its faces at the level's end.
  std::vector<typename Energy::Sums> exact_sums_;
  std::vector<double> exact_energy_;
  std::vector<uint8_t> shrunk_mark_;
  std::vector<std::vector<uint32_t>> members_;
  std::vector<uint32_t> position_;
  std::vector<std::vector<std::pair<uint32_t, uint32_t>>> neighbours_;
  std::vector<uint8_t> dirty_mark_;
  // MergeNeighboursOfPairs: per cluster, the cluster it merged into / the one merged into
  // it in this level (kNoCluster otherwise), and the lists to rebuild.
  std::vector<uint32_t> kept_of_, gone_of_, rebuild_;
  std::vector<uint8_t> rebuild_mark_;
  std::vector<std::vector<uint32_t>> block_rebuild_, block_dirty_;
  std::vector<uint32_t> dirty_;
  // UpdateOdesInParallel's marks (all 0 between levels) and list.
  std::vector<uint8_t> affected_mark_, check_mark_;
  std::vector<uint32_t> update_;
  // OptimiseInRounds: the clusters a move of the current round touched (marks 0 between
  // rounds).
  std::vector<uint8_t> round_mark_;
  std::vector<uint32_t> round_marked_;
  // OptimiseInIndependentRounds: per cluster, the first candidate of the round that reads
  // it (kUnreserved between rounds).
  static constexpr uint32_t kUnreserved = 0xffffffffu;
  // A cluster a winner of the round's earlier steps reads.
  static constexpr uint32_t kTaken = 0xfffffffdu;
  // OptimiseInIndependentRounds hands over to the face-order rounds at a round of at
  // least this many candidates with fewer than one winner in kFewWinnersRatio.
  static constexpr size_t kFewWinnersFrom = 256, kFewWinnersRatio = 8;
  std::vector<uint32_t> open_, still_open_;
  std::vector<uint8_t> blocked_;
  std::vector<std::atomic<uint32_t>> reserve_;
  // Per face, the move it keeps from the round before (kUndecided: none kept; all so
  // between levels).
  static constexpr uint32_t kUndecided = 0xfffffffeu;
  std::vector<uint32_t> kept_target_;
  // ApplyRoundInSteps: the round's candidates (indices into its list), per candidate its
  // move as applied, per cluster the key (older step: larger) of the first open candidate
  // that reads it, and scratch.
  // A move applied in parallel with others on disjoint clusters: the sums, labels and
  // members are changed at once, its entries in the shared lists (the recorder's touched
  // and moved lists, the dirty clusters) kept here and listed afterwards in candidate order.
  struct UnlistedMove {
    static constexpr uint32_t kDirty = 6;  // triangles mark at most 4 (polygons: overflow)
    uint32_t from = 0, to = 0;
    bool applied = false, touched_from = false, touched_to = false, first_move = false;
    uint32_t dirty_count = 0;
    uint32_t dirty[kDirty] = {};
    std::vector<uint32_t> dirty_overflow;
  };
  template <typename EnergyOf>
  void ApplyMoveUnlisted(uint32_t f, uint32_t to, const EnergyOf& energy_of, UnlistedMove& move) {
    const uint32_t from = partition_.label(f);
    move.from = from;
    move.to = to;
    move.touched_from = recorder_.TouchUnlisted(from, energy_of);
    move.touched_to = recorder_.TouchUnlisted(to, energy_of);
    partition_.Move(f, to);
    round_mark_[from] = round_mark_[to] = 1;
    move.first_move = recorder_.RecordMoveUnlisted(f, from);
    move.dirty_count = 0;
    move.dirty_overflow.clear();
    OnFaceMoved(f, from, to, [&](uint32_t c) {
      if (dirty_mark_[c]) return;
      dirty_mark_[c] = 1;
      if (move.dirty_count < UnlistedMove::kDirty) {
        move.dirty[move.dirty_count++] = c;
      } else {
        move.dirty_overflow.push_back(c);
      }
    });
  }
  void ListMove(const UnlistedMove& move, uint32_t f) {
    if (move.touched_from) recorder_.ListTouched(move.from);
    if (move.touched_to) recorder_.ListTouched(move.to);
    if (move.first_move) recorder_.ListMoved(f);
    dirty_.insert(dirty_.end(), move.dirty, move.dirty + move.dirty_count);
    dirty_.insert(dirty_.end(), move.dirty_overflow.begin(), move.dirty_overflow.end());
  }
  static constexpr size_t kStepsFrom = 256, kStepsMinFrontier = 32;
  std::vector<uint32_t> step_candidates_, step_applied_;
  std::vector<UnlistedMove> step_moves_;
  std::vector<uint32_t> step_set_offset_, step_set_, step_of_face_, step_head_, step_clusters_;
  std::vector<std::atomic<uint32_t>> step_set_size_, step_pending_;
  std::vector<std::vector<uint32_t>> step_queue_;
  std::vector<uint32_t> step_frontier_, step_next_, step_next_offset_;
  std::vector<uint8_t> step_done_;
  std::vector<size_t> step_offset_;
  std::vector<size_t> boundary_offset_;
  LevelRecorder recorder_;
  uint64_t optimisation_moves_ = 0, evaluations_ = 0;

  // Optimisation scratch.
  std::vector<uint32_t> worklist_;
  detail::EmloScratch emlo_scratch_;
  absl::flat_hash_map<uint32_t, Proxy> proxy_cache_;
};

// The engine over a mesh space (faces or polygons as elements), on options.threads cores.
template <typename Space>
absl::StatusOr<MultilevelSummary> RunMeshSpace(Space& space, const MultilevelOptions& options,
                                               LevelSink& sink) {
  detail::MultilevelEngineOptions engine_options;
  engine_options.optimise = options.optimizer != MultilevelOptions::Optimizer::kNone;
  engine_options.p_percent = options.p_percent;
  engine_options.optimise_below_at_least = options.optimise_below_at_least;
  engine_options.p_percent_sweep =
      options.p_percent_rule == MultilevelOptions::PPercentRule::kSweep;
  engine_options.parallel = options.parallel;
  engine_options.pml_until = options.pml_until;
  engine_options.pml_pairs = options.pml_pairs;
  engine_options.min_clusters = options.min_clusters;
  engine_options.cancel = options.cancel;
  tbb::task_arena arena(options.threads > 0 ? options.threads : tbb::task_arena::automatic);
  return arena.execute([&]() -> absl::StatusOr<MultilevelSummary> {
    detail::MultilevelEngine<Space> engine(space, engine_options, sink);
    MLCLUST_ASSIGN_OR_RETURN(detail::MultilevelEngineSummary run, engine.Run());
    MultilevelSummary summary;
    summary.levels = run.levels;
    summary.final_clusters = run.final_clusters;
    summary.moves = run.moves;
    summary.final_energy = run.final_energy;
    summary.optimisation_moves = space.optimisation_moves();
    summary.evaluations = space.evaluations();
    return summary;
  });
}

// RunMultilevel with problem.polygons (ours, issue 13): the engine over the polygons
// (detail::PolygonEnergy, their dual graph, their ring test), the levels passed to `sink`
// over faces (detail::PolygonLevelSink). options.inspect_level and the summary's moves
// see the engine's own elements, the polygons.
absl::StatusOr<MultilevelSummary> RunMultilevelOnPolygons(const MeshProblem& problem,
                                                          const MultilevelOptions& options,
                                                          LevelSink& sink) {
  const MeshPolygons& polygons = *problem.polygons;
  if (polygons.num_faces() != problem.mesh->num_faces()) {
    return absl::InvalidArgumentError(absl::StrCat("polygons of ", polygons.num_faces(),
                                                   " faces for a mesh of ",
                                                   problem.mesh->num_faces(), " faces"));
  }
  if (options.connectivity_guard && options.optimizer != MultilevelOptions::Optimizer::kNone &&
      options.guard == ConnectivityGuardKind::kVertexBoundaryEdgeCount) {
    return absl::InvalidArgumentError(
        "guard: Alg. 3.2's vertex boundary-edge counts are per triangle; with polygons use the "
        "ring test (or none)");
  }
  detail::PolygonLevelSink face_sink(polygons, sink);
  return WithMeshEnergy(problem.energy, *problem.mesh, *problem.measures,
                        [&](const auto& triangles) -> absl::StatusOr<MultilevelSummary> {
                          using Energy = detail::PolygonEnergy<std::decay_t<decltype(triangles)>>;
                          const Energy energy(triangles, polygons);
                          using Space = MeshSpace<Energy, PolygonAdjacency>;
                          Space space(problem, energy, options, polygons.adjacency);
                          return RunMeshSpace(space, options, face_sink);
                        });
}

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
  if (problem.polygons != nullptr) return RunMultilevelOnPolygons(problem, options, sink);
  return WithMeshEnergy(problem.energy, *problem.mesh, *problem.measures,
                        [&](const auto& energy) -> absl::StatusOr<MultilevelSummary> {
                          using Energy = std::decay_t<decltype(energy)>;
                          MeshSpace<Energy> space(problem, energy, options, *problem.adjacency);
                          return RunMeshSpace(space, options, sink);
                        });
}

}  // namespace mlclust
