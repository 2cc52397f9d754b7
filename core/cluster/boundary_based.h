// Boundary-based optimisation (Alg. 5.1) as four stages with small interfaces, so that a
// device backend replaces one stage and nothing else (the conflict rule and the sweep
// logic live here only):
//
//   1. FitProxies        every cluster's proxy from its sums; fixed for the sweep
//   2. decide            every face alone, against the fixed proxies: the neighbouring
//                        cluster whose proxy fits it better (DecideBoundaryMove is the
//                        rule; CpuBoundaryDecider runs it in parallel on the CPU)
//   3. ResolveConflicts  which proposals apply this sweep: of faces that share a vertex
//                        the smaller id wins, and the connectivity guard vetoes the rest
//   4. ApplyMoves        the accepted moves into the partition (UndoMoves reverts a sweep)
//
// RunBoundaryBased drives the stages with any decide stage; OptimizeBoundaryBased
// (mesh_clustering.h) is RunBoundaryBased with CpuBoundaryDecider. Internal to core and
// the device backends; callers use OptimizeBoundaryBased.
#ifndef MLCLUST_CORE_CLUSTER_BOUNDARY_BASED_H_
#define MLCLUST_CORE_CLUSTER_BOUNDARY_BASED_H_

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <type_traits>
#include <utility>
#include <vector>

#include "absl/functional/function_ref.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"
#include "core/base/ids.h"
#include "core/base/renumber.h"
#include "core/base/status_macros.h"
#include "core/base/tolerance.h"
#include "core/cluster/mesh_clustering.h"
#include "core/cluster/partition.h"
#include "core/energy/energies.h"
#include "core/mesh/connectivity_guard.h"
#include "core/mesh/mesh.h"

namespace mlclust::boundary_based {

// "This face stays": the decide stage's answer for a face with no better cluster.
inline constexpr uint32_t kNoMove = ClusterId::kInvalidValue;

// Runs the stages' parallel loops on a fixed number of threads (0: all cores). One per
// run; the loops' results do not depend on the thread count.
class StageThreads {
 public:
  explicit StageThreads(int threads);
  ~StageThreads();
  StageThreads(const StageThreads&) = delete;
  StageThreads& operator=(const StageThreads&) = delete;

  // body(begin, end) over disjoint blocks covering [0, n), blocks of about `grain`.
  void ParallelFor(size_t n, size_t grain, absl::FunctionRef<void(size_t, size_t)> body) const;

 private:
  struct Arena;
  std::unique_ptr<Arena> arena_;
};

// Stage 1: proxies[c] = FitProxy(sums of c) for every cluster id (empty ones included).
template <typename Energy>
void FitProxies(const Partition<Energy>& partition, std::vector<typename Energy::Proxy>& proxies) {
  proxies.resize(partition.capacity());
  for (uint32_t c = 0; c < partition.capacity(); ++c) {
    proxies[c] = partition.energy().FitProxy(partition.sums(c));
  }
}

// Stage 2's rule for one face: among the clusters of its edge neighbours other than its
// own, the one whose proxy gives the smallest FaceCost (the first in edge order on ties),
// if that cost is below the face's cost against its own proxy by more than rounding
// (kRelativeImprovement); kNoMove otherwise. A device decide stage must give the same
// answer (up to its arithmetic). `label(f)` is face f's cluster and `proxy(c)` cluster c's
// proxy, asked in this order (own first, then each new neighbouring cluster): the sweeps
// read fixed arrays (DecideBoundaryMove), ML's local BB its live partition and a lazy
// proxy cache (multilevel.cc).
// `adjacency` is a FaceAdjacency or the polygons' PolygonAdjacency (core/mesh/polygons.h).
template <typename Energy, typename Adjacency, typename LabelOf, typename ProxyOf>
uint32_t DecideBoundaryMoveWith(const Energy& energy, const Adjacency& adjacency, uint32_t face,
                                const LabelOf& label, const ProxyOf& proxy) {
  const uint32_t own = label(face);
  double best = energy.FaceCost(face, proxy(own));
  const double own_cost = best;
  uint32_t best_cluster = own;
  for (FaceId g : adjacency.neighbours[face]) {
    if (!g.valid()) continue;
    const uint32_t c = label(g.value());
    if (c == own || c == best_cluster) continue;
    const double cost = energy.FaceCost(face, proxy(c));
    if (cost < best) {
      best = cost;
      best_cluster = c;
    }
  }
  return best_cluster != own && own_cost - best > kRelativeImprovement * own_cost ? best_cluster
                                                                                  : kNoMove;
}

// DecideBoundaryMoveWith over a sweep's fixed labels and proxies.
template <typename Energy, typename Adjacency = FaceAdjacency>
uint32_t DecideBoundaryMove(const Energy& energy, const Adjacency& adjacency,
                            std::span<const uint32_t> labels,
                            std::span<const typename Energy::Proxy> proxies, uint32_t face) {
  return DecideBoundaryMoveWith(
      energy, adjacency, face, [labels](uint32_t f) { return labels[f]; },
      [proxies](uint32_t c) -> const typename Energy::Proxy& { return proxies[c]; });
}

// Stage 2 on the CPU: target[f] = DecideBoundaryMove(f) for every face, in parallel.
// The shape every decide stage has:
//   absl::Status operator()(labels, proxies, target)   (target.size() == faces)
template <typename Energy, typename Adjacency = FaceAdjacency>
class CpuBoundaryDecider {
 public:
  CpuBoundaryDecider(const Energy& energy, const Adjacency& adjacency, const StageThreads& threads)
      : energy_(energy), adjacency_(adjacency), threads_(threads) {}

  absl::Status operator()(std::span<const uint32_t> labels,
                          std::span<const typename Energy::Proxy> proxies,
                          std::span<uint32_t> target) const {
    threads_.ParallelFor(target.size(), 4096, [&](size_t begin, size_t end) {
      for (size_t f = begin; f != end; ++f) {
        target[f] =
            DecideBoundaryMove(energy_, adjacency_, labels, proxies, static_cast<uint32_t>(f));
      }
    });
    return absl::OkStatus();
  }

 private:
  const Energy& energy_;
  const Adjacency& adjacency_;
  const StageThreads& threads_;
};

// Work memory of ResolveConflicts, reused across sweeps.
struct ConflictScratch {
  std::vector<uint32_t> proposed;
  std::vector<uint8_t> accept;
  std::vector<uint8_t> allowed;  // per face: proposes a move the guard allows
};

// Stage 3, the one conflict rule: the faces whose proposed move (target[f] != kNoMove)
// applies this sweep, in increasing face order, into `accepted`. First the connectivity
// check `allowed(face, to)` (asked against the sweep's starting state, in parallel, so it
// must be safe to call concurrently) drops the proposals it refuses; then, of the
// proposals left, one is dropped if a face with a smaller id that shares a vertex with it
// (its ring in `rings`) is also left. So no two accepted faces touch, and each accepted
// move's check stays valid when all are applied. A refused proposal does not block the
// faces around it: when it did, the same refused face blocked its neighbours again in
// every sweep, and BB stopped at K = 2000 on bunny about 30 % above EMLO (BENCHMARKS.md,
// "BB against EMLO: why the guard cost 30 %").
void ResolveConflicts(const ConnectivityGuard& rings,
                      absl::FunctionRef<bool(uint32_t face, uint32_t to)> allowed,
                      std::span<const uint32_t> target, const StageThreads& threads,
                      ConflictScratch& scratch, std::vector<uint32_t>& accepted);

// The same with `guard`'s ring test against `labels` and `sizes` as the check (none
// without `check_connectivity`).
void ResolveConflicts(const ConnectivityGuard& guard, bool check_connectivity,
                      std::span<const uint32_t> labels, std::span<const uint32_t> sizes,
                      std::span<const uint32_t> target, const StageThreads& threads,
                      ConflictScratch& scratch, std::vector<uint32_t>& accepted);

// A face's cluster before a move, to undo it.
struct AppliedMove {
  uint32_t face;
  uint32_t from;
};

// Stage 4: moves each accepted face to target[face], in order, skipping a face that is
// the last of its cluster (no cluster disappears). The moves made go to `applied`.
template <typename Energy>
void ApplyMoves(Partition<Energy>& partition, std::span<const uint32_t> accepted,
                std::span<const uint32_t> target, std::vector<AppliedMove>& applied) {
  applied.clear();
  for (uint32_t f : accepted) {
    if (partition.size(partition.label(f)) <= 1) continue;
    applied.push_back({f, partition.label(f)});
    partition.Move(f, target[f]);
  }
}

// Reverts ApplyMoves' moves, last first.
template <typename Energy>
void UndoMoves(Partition<Energy>& partition, std::span<const AppliedMove> applied) {
  for (auto it = applied.rbegin(); it != applied.rend(); ++it) partition.Move(it->face, it->from);
}

// The sweeps of Alg. 5.1 over `partition` with the decide stage `decide` (the shape of
// CpuBoundaryDecider::operator()): fit, decide, resolve, apply until nothing moves, a sweep
// would raise the energy (it is undone; possible only for MWCVD, whose weights are not
// fitted) or options.max_iterations sweeps. The check is options.guard (none without
// options.connectivity_guard): `guard`'s ring test, or Alg. 3.2 with `counts`, which must
// then be non-null and is Reset to the partition's labels here and kept up to date.
// Checks options.cancel before every stage. Returns the decide stage's error, CANCELLED,
// INVALID_ARGUMENT (Alg. 3.2 asked for without counts), or the result; on an error the
// partition is valid but not converged.
template <typename Energy, typename Decide>
absl::StatusOr<OptimizeResult> RunBoundaryBased(const ConnectivityGuard& guard,
                                                VertexBoundaryEdgeCountGuard* counts,
                                                Partition<Energy>& partition,
                                                const BoundaryBasedOptions& options,
                                                const StageThreads& threads, Decide&& decide) {
  const ConnectivityGuardKind kind =
      options.connectivity_guard ? options.guard : ConnectivityGuardKind::kOff;
  if (kind == ConnectivityGuardKind::kVertexBoundaryEdgeCount) {
    if (counts == nullptr) {
      return absl::InvalidArgumentError(
          "guard: Alg. 3.2's vertex boundary-edge counts were not given to BB");
    }
    counts->Reset(partition.labels());
  }
  auto allowed = [&](uint32_t face, uint32_t to) {
    switch (kind) {
      case ConnectivityGuardKind::kRingTest:
        return guard.CanMove(face, to, partition.labels(), partition.sizes());
      case ConnectivityGuardKind::kVertexBoundaryEdgeCount:
        return counts->CanMove(face, to, partition.labels(), partition.sizes());
      case ConnectivityGuardKind::kOff:
        break;
    }
    return true;
  };
  const size_t n = partition.labels().size();
  OptimizeResult result;
  result.initial_energy = partition.TotalEnergy();
  result.converged = false;
  double current = result.initial_energy;
  std::vector<typename Energy::Proxy> proxies;
  std::vector<uint32_t> target(n, kNoMove);
  ConflictScratch scratch;
  std::vector<uint32_t> accepted;
  std::vector<AppliedMove> applied;
  for (uint32_t iteration = 1; iteration <= options.max_iterations; ++iteration) {
    MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "BB fit proxies"));
    FitProxies(partition, proxies);
    MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "BB decide moves"));
    MLCLUST_RETURN_IF_ERROR(decide(partition.labels(),
                                   std::span<const typename Energy::Proxy>(proxies),
                                   std::span<uint32_t>(target)));
    MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "BB resolve conflicts"));
    ResolveConflicts(guard, allowed, target, threads, scratch, accepted);
    ApplyMoves(partition, accepted, target, applied);
    if (kind == ConnectivityGuardKind::kVertexBoundaryEdgeCount) {
      for (const AppliedMove& move : applied) {
        counts->OnMove(move.face, move.from, partition.labels());
      }
    }
    result.iterations = iteration;
    if (applied.empty()) {
      result.converged = true;
      break;
    }
    const double next = partition.TotalEnergy();
    if (next > current) {
      UndoMoves(partition, std::span<const AppliedMove>(applied));
      if (kind == ConnectivityGuardKind::kVertexBoundaryEdgeCount) {
        counts->Reset(partition.labels());
      }
      result.converged = true;
      break;
    }
    current = next;
    result.moves += applied.size();
    if (options.on_iteration) options.on_iteration(iteration, current);
  }
  partition.RefreshAllSums();  // the energy of the labels (partition.h)
  result.energy = partition.TotalEnergy();
  return result;
}

// The same without Alg. 3.2's counts (options.guard must not ask for them).
template <typename Energy, typename Decide>
absl::StatusOr<OptimizeResult> RunBoundaryBased(const ConnectivityGuard& guard,
                                                Partition<Energy>& partition,
                                                const BoundaryBasedOptions& options,
                                                const StageThreads& threads, Decide&& decide) {
  return RunBoundaryBased(guard, nullptr, partition, options, threads,
                          std::forward<Decide>(decide));
}

// The whole of OptimizeBoundaryBased (mesh_clustering.h) with the decide stage that
// `make_decide(energy, num_clusters, threads)` builds for the problem's energy (clusters
// renumbered 0..num_clusters-1 by first appearance): it returns an
// absl::StatusOr of a decide stage (CpuBoundaryDecider, or a device's). The same checks,
// compact labels, partition, guards and sweeps, so a device backend replaces the decide
// stage and nothing else (gpu/stages/boundary_based_gpu.cc). On an error `labels` are
// unchanged.
template <typename MakeDecide>
absl::StatusOr<OptimizeResult> OptimizeBoundaryBasedWith(const MeshProblem& problem,
                                                         std::vector<ClusterId>& labels,
                                                         const BoundaryBasedOptions& options,
                                                         MakeDecide&& make_decide) {
  MLCLUST_RETURN_IF_ERROR(ValidateMeshProblem(problem));
  if (problem.polygons != nullptr) {
    // OptimizeBoundaryBased runs polygons on the CPU (a device decide stage is per face).
    return absl::InvalidArgumentError("polygons: BB with a device decide stage is per triangle");
  }
  const size_t n = problem.mesh->num_faces();
  if (labels.size() != n) {
    return absl::InvalidArgumentError(
        absl::StrCat("labels: ", labels.size(), " for a mesh of ", n, " faces"));
  }
  if (options.threads < 0) {
    return absl::InvalidArgumentError(absl::StrCat("threads: ", options.threads, " < 0"));
  }
  const Renumbering<ClusterId> renumbered =
      RenumberByFirstAppearance(std::span<const ClusterId>(labels));
  const uint32_t k = renumbered.size();
  const StageThreads threads(options.threads);
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "BB set-up"));
  auto run = [&](const auto& energy) -> absl::StatusOr<OptimizeResult> {
    using Energy = std::decay_t<decltype(energy)>;
    Partition<Energy> partition(energy, renumbered.dense, k);
    MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "BB set-up"));
    MLCLUST_ASSIGN_OR_RETURN(
        const ConnectivityGuard guard,
        ConnectivityGuard::Build(*problem.mesh, *problem.adjacency, options.cancel));
    auto decide = make_decide(energy, k, threads);
    if (!decide.ok()) return decide.status();
    // The ring structure always: the conflict rule reads it whatever the guard.
    std::optional<VertexBoundaryEdgeCountGuard> counts;
    if (options.guard == ConnectivityGuardKind::kVertexBoundaryEdgeCount) {
      counts.emplace(*problem.mesh, *problem.adjacency);
    }
    MLCLUST_ASSIGN_OR_RETURN(OptimizeResult result,
                             RunBoundaryBased(guard, counts.has_value() ? &*counts : nullptr,
                                              partition, options, threads, *decide));
    const std::span<const uint32_t> compact = partition.labels();
    for (size_t f = 0; f < n; ++f) labels[f] = renumbered.original[compact[f]];
    return result;
  };
  return WithMeshEnergy(problem.energy, *problem.mesh, *problem.measures, run);
}

}  // namespace mlclust::boundary_based

#endif  // MLCLUST_CORE_CLUSTER_BOUNDARY_BASED_H_
