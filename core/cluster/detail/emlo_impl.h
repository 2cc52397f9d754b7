// EMLO, energy minimisation by local optimisation (Alg. 3.3), over a Partition. Internal:
// the public entry is OptimizeEmlo in core/mesh_clustering.h; the multilevel engine runs
// it locally after each merge.
#ifndef MLCLUST_CORE_CLUSTER_DETAIL_EMLO_IMPL_H_
#define MLCLUST_CORE_CLUSTER_DETAIL_EMLO_IMPL_H_

#include <atomic>
#include <cstdint>
#include <deque>
#include <span>
#include <vector>

#include "core/base/cancel.h"
#include "core/base/tolerance.h"
#include "core/cluster/partition.h"
#include "core/mesh/connectivity_guard.h"
#include "core/mesh/mesh.h"

namespace mlclust::detail {

struct EmloCounters {
  uint64_t moves = 0;
  uint64_t evaluations = 0;  // boundary edges compared
  bool hit_move_limit = false;
  bool cancelled = false;  // the cancel flag was seen set; the partition is valid
};

// How many faces EMLO takes off its worklist between two looks at the cancel flag: each
// costs at most three boundary-edge comparisons, so a look every 4096 is well under a
// millisecond apart.
inline constexpr uint32_t kEmloFacesPerCancelCheck = 4096;

// Work memory reused across runs (the multilevel engine runs EMLO once per level, so
// nothing of size O(faces) may be allocated per run).
struct EmloScratch {
  std::vector<uint8_t> queued;
  std::deque<uint32_t> queue;
};

// Runs EMLO from the faces in `worklist` (any faces; those not on a cluster boundary are
// skipped) until no face on a boundary can lower the energy, or `max_moves` moves.
// For a boundary edge between face f in A and face g in B the three cases of eqs.
// 3.33-3.35 are compared from the two clusters' sums only:
//   E(A) + E(B),   E(A - f) + E(B + f),   E(A + g) + E(B - g)
// and the cheapest is applied if it lowers the energy by more than rounding. Every move
// strictly lowers the energy of the two clusters it touches, so the run ends. `guard` (may
// be null; a ConnectivityGuard or a VertexBoundaryEdgeCountGuard, whose counts `on_move`
// must then keep) vetoes moves that would split or pierce a cluster. `on_move(face, from, to)` is
// called after each move. Faces whose neighbourhood changed go back on the worklist.
// `before_move(from, to)` runs just before each move (the engine records the two clusters'
// energies then). A set `cancel` (may be null) stops the run within
// kEmloFacesPerCancelCheck faces with counters.cancelled; the scratch is left clean.
// `adjacency` is a FaceAdjacency, or any neighbour lists read the same way (the polygons'
// PolygonAdjacency, core/mesh/polygons.h, whose elements are polygons).
template <typename Energy, typename OnMove, typename BeforeMove, typename Guard, typename Adjacency>
EmloCounters RunEmloOn(const Adjacency& adjacency, const Guard* guard, Partition<Energy>& partition,
                       std::span<const uint32_t> worklist, uint64_t max_moves, EmloScratch& scratch,
                       OnMove&& on_move, BeforeMove&& before_move,
                       const std::atomic<bool>* cancel) {
  const Energy& energy = partition.energy();
  using Sums = typename Energy::Sums;
  EmloCounters counters;
  const size_t n = adjacency.num_faces();
  std::vector<uint8_t>& queued = scratch.queued;
  std::deque<uint32_t>& queue = scratch.queue;
  if (queued.size() != n) queued.assign(n, 0);
  queue.clear();
  for (uint32_t f : worklist) {
    if (!queued[f]) {
      queued[f] = 1;
      queue.push_back(f);
    }
  }
  auto enqueue_around = [&](uint32_t face) {
    if (!queued[face]) {
      queued[face] = 1;
      queue.push_back(face);
    }
    for (FaceId g : adjacency.neighbours[face]) {
      if (g.valid() && !queued[g.value()]) {
        queued[g.value()] = 1;
        queue.push_back(g.value());
      }
    }
  };
  auto apply = [&](uint32_t face, uint32_t to) {
    const uint32_t from = partition.label(face);
    before_move(from, to);
    partition.Move(face, to);
    ++counters.moves;
    on_move(face, from, to);
    enqueue_around(face);
  };

  uint32_t until_cancel_check = kEmloFacesPerCancelCheck;
  while (!queue.empty()) {
    if (--until_cancel_check == 0) {
      until_cancel_check = kEmloFacesPerCancelCheck;
      counters.cancelled = IsCancelled(cancel);
    }
    if (counters.moves >= max_moves || counters.cancelled) {
      counters.hit_move_limit = !counters.cancelled;
      for (uint32_t f : queue) queued[f] = 0;  // leave the scratch clean
      queue.clear();
      break;
    }
    const uint32_t f = queue.front();
    queue.pop_front();
    queued[f] = 0;
    for (FaceId neighbour : adjacency.neighbours[f]) {
      if (!neighbour.valid()) continue;
      const uint32_t g = neighbour.value();
      const uint32_t a = partition.label(f), b = partition.label(g);
      if (a == b) continue;
      ++counters.evaluations;
      const Sums& face_f = energy.face_sums(f);
      const Sums& face_g = energy.face_sums(g);
      const double keep = partition.cluster_energy(a) + partition.cluster_energy(b);
      double best = keep;
      int choice = 0;
      if (partition.size(a) > 1) {
        Sums a_without = partition.sums(a);
        a_without -= face_f;
        const double e = energy.Energy(a_without) + energy.Energy(partition.sums(b) + face_f);
        if (e < best) {
          best = e;
          choice = 1;
        }
      }
      if (partition.size(b) > 1) {
        Sums b_without = partition.sums(b);
        b_without -= face_g;
        const double e = energy.Energy(partition.sums(a) + face_g) + energy.Energy(b_without);
        if (e < best) {
          best = e;
          choice = 2;
        }
      }
      // Rounding in the sums is ~1e-16 relative; demand a real improvement.
      if (choice == 0 || keep - best <= kRelativeImprovement * keep) continue;
      const uint32_t face = choice == 1 ? f : g;
      const uint32_t to = choice == 1 ? b : a;
      if (guard != nullptr && !guard->CanMove(face, to, partition.labels(), partition.sizes())) {
        // The best move is vetoed; the other one may still help.
        const uint32_t other_face = choice == 1 ? g : f;
        const uint32_t other_to = choice == 1 ? a : b;
        const uint32_t other_from = choice == 1 ? b : a;
        if (partition.size(other_from) <= 1) continue;
        Sums from_without = partition.sums(other_from);
        from_without -= energy.face_sums(other_face);
        const double e = energy.Energy(from_without) +
                         energy.Energy(partition.sums(other_to) + energy.face_sums(other_face));
        if (keep - e > kRelativeImprovement * keep &&
            guard->CanMove(other_face, other_to, partition.labels(), partition.sizes())) {
          apply(other_face, other_to);
          if (other_face == f) break;
        }
        continue;
      }
      apply(face, to);
      if (face == f) break;  // f's label changed: it is queued again
    }
  }
  return counters;
}

template <typename Energy, typename OnMove, typename BeforeMove>
EmloCounters RunEmloOn(const FaceAdjacency& adjacency, const ConnectivityGuard* guard,
                       Partition<Energy>& partition, std::span<const uint32_t> worklist,
                       uint64_t max_moves, EmloScratch& scratch, OnMove&& on_move,
                       BeforeMove&& before_move) {
  return RunEmloOn(adjacency, guard, partition, worklist, max_moves, scratch, on_move, before_move,
                   nullptr);
}

template <typename Energy, typename OnMove>
EmloCounters RunEmloOn(const FaceAdjacency& adjacency, const ConnectivityGuard* guard,
                       Partition<Energy>& partition, std::span<const uint32_t> worklist,
                       uint64_t max_moves, EmloScratch& scratch, OnMove&& on_move) {
  return RunEmloOn(
      adjacency, guard, partition, worklist, max_moves, scratch, on_move, [](uint32_t, uint32_t) {},
      nullptr);
}

// The faces (elements of `adjacency`) that have a neighbour in another cluster.
template <typename Energy, typename Adjacency>
std::vector<uint32_t> BoundaryFaces(const Adjacency& adjacency,
                                    const Partition<Energy>& partition) {
  std::vector<uint32_t> faces;
  for (uint32_t f = 0; f < adjacency.num_faces(); ++f) {
    for (FaceId g : adjacency.neighbours[f]) {
      if (g.valid() && partition.label(g.value()) != partition.label(f)) {
        faces.push_back(f);
        break;
      }
    }
  }
  return faces;
}

}  // namespace mlclust::detail

#endif  // MLCLUST_CORE_CLUSTER_DETAIL_EMLO_IMPL_H_
