// The multilevel engine: ML (Alg. 4.1), its p% variant (Alg. 4.2), PML (Alg. 5.3) and HC
// (Alg. 2.3, the same engine without optimisation), over every mesh energy.
//
// Start: one cluster per face (cluster id = face id). ML repeats: merge the pair of
// adjacent clusters with the smallest dual-edge cost E(A u B) - E(A) - E(B) (eq. 4.1),
// then optimise locally around the merged cluster (EMLO for energies with an incremental
// form, BB for proxy-only ones, or none), spreading outward only while something
// changes. Every level goes to a LevelSink as the faces whose cluster changed, with the
// cluster count and the energy (kept from sums, never re-scanned).
//
// The engine is core/cluster/detail/multilevel_engine.h, shared with the points' ML
// (core/cluster/point_clustering.h): the same ODE rules, ties, PML pair rule and levels.
#ifndef MLCLUST_CORE_CLUSTER_MULTILEVEL_H_
#define MLCLUST_CORE_CLUSTER_MULTILEVEL_H_

#include <atomic>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "absl/status/statusor.h"
#include "core/cluster/detail/pml_pairs.h"
#include "core/cluster/mesh_clustering.h"
#include "core/hierarchy/hierarchy.h"

namespace mlclust {

struct MultilevelOptions {
  enum class Optimizer {
    kEmlo,           // local EMLO after each merge (the default)
    kBoundaryBased,  // local boundary-based sweeps with proxies fixed per sweep
    kNone,           // HC: merges only
  };
  Optimizer optimizer = Optimizer::kEmlo;
  // Alg. 4.2: merge this percentage of the clusters first without optimisation, then
  // continue as ML. 0 (the default) is plain ML. How the first p% merge:
  //   kSweep (Alg. 4.2, l. 1868, the default): in one level, sweeps over the clusters in id
  //     order, each collapsing its optimal dual edge unless the other cluster already took
  //     part in a merge of this sweep, until p% of the clusters have merged;
  //   kHcFirst (ours, the former rule): one level per merge, cheapest first, as HC; p = 100
  //     is HC.
  enum class PPercentRule { kSweep, kHcFirst };
  double p_percent = 0;
  PPercentRule p_percent_rule = PPercentRule::kSweep;
  // Ours (the registry's pml preset many-cores): with p_percent, the merges are optimised
  // at least below this many clusters (0: p_percent alone decides).
  uint32_t optimise_below_at_least = 0;
  // PML (Alg. 5.3): collapse all mutual optimal dual edges at once per level (ties to the
  // larger id) while more than `pml_until` clusters are left, then continue as ML. 0: PML
  // to the end.
  bool parallel = false;
  uint32_t pml_until = 0;
  // Which mutual pairs a PML level collapses: kAll, every one (Alg. 5.3), or
  // kCheaperHalf (ours, the default), those that cost at most the level's median mutual
  // pair (core/cluster/detail/pml_pairs.h). Measured on fandisk, bunny00, armadillo and
  // elephant with CVD and planar, PML to the end, energy at the first level with at most
  // 1000/200/50 clusters over ML's at the same count: kAll 1.00-1.46x (median 1.09x),
  // kCheaperHalf 0.98-1.08x (median 1.00x) (bench/pml_pairs_bench.sh, BENCHMARKS.md;
  // fandisk planar excluded: both rules give the same, far above ML).
  PmlPairRule pml_pairs = PmlPairRule::kCheaperHalf;
  // Stop at this many clusters (>= 1); a mesh with C components stops at C at the least.
  uint32_t min_clusters = 1;
  bool connectivity_guard = true;
  // Which guard the local optimisation asks, with connectivity_guard: the ring test (ours,
  // the default) or Alg. 3.2 (kVertexBoundaryEdgeCount, l. 870-890), read without kept
  // counts (VertexBoundaryEdgeCountGuard::CanMoveWithoutCounts) since a merge relabels a
  // whole cluster at once. kOff is the same as connectivity_guard = false.
  ConnectivityGuardKind guard = ConnectivityGuardKind::kRingTest;
  // Equal ODE costs: true (the default), the cluster with the fewest faces merges first
  // (footnote 4 of section 4.2, l. 1588), then the smaller id; false, the smaller id
  // alone (the former rule). Which partner a cluster's ODE names among equal costs is
  // the larger id either way (PML's rule, Alg. 5.3).
  bool ties_to_fewest_faces = true;
  // Worker threads for PML's parallel steps, 0 = all cores. The levels do not depend on
  // it.
  int threads = 0;
  // Ours: the local optimisation of a PML level (and of the hand-over to ML) in parallel
  // rounds instead of EMLO's one queue: every face of the round's work list finds in
  // parallel, from the sums as the round found them, the neighbouring cluster it would
  // most lower the energy by joining (eqs. 3.33-3.35, the face's own move); then, in face
  // order, each such move is checked again against the sums as they are by then and
  // applied if it still lowers the energy and the connectivity guard allows it; the
  // moved faces and their neighbours make the next round's list, until none moves. Each
  // move lowers the energy, as EMLO's; the result differs from EMLO's (another order of
  // moves) and does not depend on the thread count. EMLO optimiser only; ML levels keep
  // EMLO's queue.
  bool parallel_optimisation = false;
  // Ours, with parallel_optimisation and the ring guard (or none): each round applies a
  // set of moves on pairwise disjoint clusters (a face reads the clusters of the faces
  // around it; the first maximal such set in face order), checked by the guard and applied
  // without the one-by-one re-check, all found in parallel; the other moves wait for the
  // next round. A round of at least 256 candidates with fewer than one winner in 8 hands
  // the rest of the level to the face-order rounds above (a cluster takes one move per
  // round, so a boundary moving by many faces would need a round per face). Each move
  // lowers the energy; the result differs from the rounds' face-order application and does
  // not depend on the thread count. With the vertex-count guard the rounds apply in face
  // order as before.
  bool independent_moves = false;
  // Set from any thread to stop the run: checked every 16,384 faces while the clusters'
  // adjacency is built, while the connectivity guard is built, inside local EMLO (every
  // few thousand faces), after every level and every 65,536 ODEs of the first ODE pass and
  // of a p% sweep. The run then returns CANCELLED (core/base/cancel.h).
  const std::atomic<bool>* cancel = nullptr;
  // Called at each level after it is reported, with the engine's own labels (one cluster
  // id per face). For tests that check the log against the engine; costs O(faces) a call.
  std::function<void(size_t level, std::span<const uint32_t> labels)> inspect_level;
};

struct MultilevelSummary {
  uint32_t levels = 0;  // level 0 included
  uint32_t final_clusters = 0;
  uint64_t moves = 0;               // triplets reported
  uint64_t optimisation_moves = 0;  // face moves made by the optimiser, before squashing
  uint64_t evaluations = 0;         // boundary edges the optimiser compared
  double final_energy = 0;
};

// Runs the engine and reports every level to `sink` (level 0: every face its own cluster,
// energy 0 for every energy here). INVALID_ARGUMENT for out-of-range options; CANCELLED
// once `options.cancel` is set; the sink's status if it stops the run.
absl::StatusOr<MultilevelSummary> RunMultilevel(const MeshProblem& problem,
                                                const MultilevelOptions& options, LevelSink& sink);

}  // namespace mlclust

#endif  // MLCLUST_CORE_CLUSTER_MULTILEVEL_H_
