#include "core/cluster/mesh_clustering.h"

#include <algorithm>
#include <numeric>
#include <queue>

#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"
#include "core/base/random.h"
#include "core/base/renumber.h"
#include "core/base/status_macros.h"
#include "core/cluster/boundary_based.h"
#include "core/cluster/detail/emlo_impl.h"
#include "core/cluster/partition.h"
#include "core/mesh/connectivity_guard.h"

namespace mlclust {
namespace {

// A face not yet in a cluster: the cluster id type's own sentinel.
constexpr uint32_t kUnassigned = ClusterId::kInvalidValue;

// Loops over faces look at the cancel flag once per this many faces (well under a
// millisecond of work on any of them).
constexpr uint32_t kFacesPerCancelCheck = 16384;

// Alg. 2.2's flood: each seed's proxy is fitted to the seed face; faces join the region
// whose proxy fits them best among regions that reach them, cheapest first.
// Empty if `cancel` was seen set (checked every kFacesPerCancelCheck faces).
template <typename Energy>
std::vector<uint32_t> GrowFromSeeds(const Energy& energy, const FaceAdjacency& adjacency,
                                    std::span<const uint32_t> seeds,
                                    const std::atomic<bool>* cancel) {
  using Proxy = typename Energy::Proxy;
  std::vector<uint32_t> labels(adjacency.num_faces(), kUnassigned);
  std::vector<Proxy> proxies;
  proxies.reserve(seeds.size());
  struct Candidate {
    double cost;
    uint64_t order;  // ties: first pushed first, so the flood is deterministic
    uint32_t face, cluster;
    bool operator>(const Candidate& o) const {
      return cost != o.cost ? cost > o.cost : order > o.order;
    }
  };
  std::priority_queue<Candidate, std::vector<Candidate>, std::greater<>> queue;
  uint64_t order = 0;
  auto push_neighbours = [&](uint32_t face, uint32_t cluster) {
    for (FaceId g : adjacency.neighbours[face]) {
      if (g.valid() && labels[g.value()] == kUnassigned) {
        queue.push({energy.FaceCost(g.value(), proxies[cluster]), order++, g.value(), cluster});
      }
    }
  };
  for (uint32_t c = 0; c < seeds.size(); ++c) {
    proxies.push_back(energy.FitProxy(energy.face_sums(seeds[c])));
    labels[seeds[c]] = c;
  }
  for (uint32_t c = 0; c < seeds.size(); ++c) push_neighbours(seeds[c], c);
  uint32_t until_cancel_check = kFacesPerCancelCheck;
  while (!queue.empty()) {
    if (--until_cancel_check == 0) {
      until_cancel_check = kFacesPerCancelCheck;
      if (IsCancelled(cancel)) return {};
    }
    const Candidate next = queue.top();
    queue.pop();
    if (labels[next.face] != kUnassigned) continue;
    labels[next.face] = next.cluster;
    push_neighbours(next.face, next.cluster);
  }
  return labels;
}

// Section 3.1.5: merge the three clusters meeting at a vertex with the smallest summed
// area until `target` clusters are left (a pair across an edge for the last step when the
// parity needs it). Returns labels renumbered 0..target-1.
// Empty if `cancel` was seen set.
std::vector<uint32_t> ReduceToK(const TriangleMesh& mesh, const FaceAdjacency& adjacency,
                                const FaceMeasures& measures, std::vector<uint32_t> labels,
                                uint32_t clusters, uint32_t target,
                                const std::atomic<bool>* cancel) {
  std::vector<uint32_t> parent(clusters);
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](uint32_t c) {
    while (parent[c] != c) c = parent[c] = parent[parent[c]];
    return c;
  };
  std::vector<double> area(clusters, 0.0);
  std::vector<std::vector<uint32_t>> members(clusters);
  for (uint32_t f = 0; f < labels.size(); ++f) {
    area[labels[f]] += measures.area[f];
    members[labels[f]].push_back(f);
  }
  // Distinct clusters around each vertex, from its faces.
  const size_t num_vertices = mesh.num_vertices();
  const VertexFaceTable table = BuildVertexFaceTable(mesh);
  auto clusters_at = [&](uint32_t v, uint32_t out[4]) {
    int count = 0;
    for (uint32_t face : table.faces_around(v)) {
      if (count == 4) break;
      const uint32_t c = find(labels[face]);
      if (std::find(out, out + count, c) == out + count) out[count++] = c;
    }
    return count;
  };
  using Entry = std::pair<double, uint32_t>;  // summed area, vertex
  std::priority_queue<Entry, std::vector<Entry>, std::greater<>> triples;
  auto consider = [&](uint32_t v) {
    uint32_t around[4];
    if (clusters_at(v, around) == 3) {
      triples.push({area[around[0]] + area[around[1]] + area[around[2]], v});
    }
  };
  for (uint32_t v = 0; v < num_vertices; ++v) consider(v);
  auto merge_into = [&](uint32_t keep, uint32_t gone) {
    if (members[gone].size() > members[keep].size()) std::swap(keep, gone);
    parent[gone] = keep;
    area[keep] += area[gone];
    for (uint32_t f : members[gone]) labels[f] = keep;
    members[keep].insert(members[keep].end(), members[gone].begin(), members[gone].end());
    std::vector<uint32_t>().swap(members[gone]);
    return keep;
  };
  uint32_t count = clusters;
  uint32_t until_cancel_check = kFacesPerCancelCheck;
  while (count >= target + 2 && !triples.empty()) {
    if (--until_cancel_check == 0) {
      until_cancel_check = kFacesPerCancelCheck;
      if (IsCancelled(cancel)) return {};
    }
    const auto [key, v] = triples.top();
    triples.pop();
    uint32_t around[4];
    if (clusters_at(v, around) != 3) continue;
    const double sum = area[around[0]] + area[around[1]] + area[around[2]];
    if (sum != key) {
      triples.push({sum, v});  // stale: areas only grow, so re-queue with the real sum
      continue;
    }
    uint32_t keep = merge_into(around[0], around[1]);
    keep = merge_into(keep, around[2]);
    count -= 2;
    for (uint32_t f : members[keep]) {
      for (int c = 0; c < 3; ++c) consider(mesh.indices[3 * size_t{f} + c]);
    }
  }
  // Pairs: the last step for parity, or all steps where no vertex joins three clusters.
  while (count > target) {
    if (IsCancelled(cancel)) return {};  // each step scans every face
    double best = std::numeric_limits<double>::infinity();
    uint32_t best_a = 0, best_b = 0;
    for (uint32_t f = 0; f < labels.size(); ++f) {
      for (FaceId g : adjacency.neighbours[f]) {
        if (!g.valid()) continue;
        const uint32_t a = find(labels[f]), b = find(labels[g.value()]);
        if (a != b && area[a] + area[b] < best) {
          best = area[a] + area[b];
          best_a = a;
          best_b = b;
        }
      }
    }
    if (best == std::numeric_limits<double>::infinity()) break;
    merge_into(best_a, best_b);
    --count;
  }
  for (uint32_t& l : labels) l = find(l);
  return RenumberByFirstAppearance(std::span<const uint32_t>(labels)).dense;
}

std::vector<ClusterId> ToClusterIds(std::span<const uint32_t> labels) {
  std::vector<ClusterId> out(labels.size());
  for (size_t i = 0; i < labels.size(); ++i) out[i] = ClusterId(labels[i]);
  return out;
}

void WriteBack(std::span<const uint32_t> compact_labels, std::span<const ClusterId> original,
               std::vector<ClusterId>& labels) {
  for (size_t f = 0; f < labels.size(); ++f) labels[f] = original[compact_labels[f]];
}

}  // namespace

namespace {

// Alg. 3.1; false (and `seeds` unspecified) if `cancel` was seen set.
bool LNeighbourhoodSeeds(const FaceAdjacency& adjacency, uint32_t level,
                         const std::atomic<bool>* cancel, std::vector<uint32_t>& seeds) {
  const size_t n = adjacency.num_faces();
  seeds.clear();
  std::vector<uint8_t> valid(n, 1);
  std::vector<uint32_t> frontier, next, visited;
  std::vector<uint32_t> stamp(n, 0);
  uint32_t stamp_value = 0;
  // The faces within `level` edge-steps of `face`, into `visited`; false as soon as one is
  // already invalid (then `face` cannot be a seed).
  auto neighbourhood_valid = [&](uint32_t face) {
    ++stamp_value;
    visited.assign(1, face);
    stamp[face] = stamp_value;
    frontier.assign(1, face);
    for (uint32_t step = 0; step < level && !frontier.empty(); ++step) {
      next.clear();
      for (uint32_t f : frontier) {
        for (FaceId g : adjacency.neighbours[f]) {
          if (!g.valid() || stamp[g.value()] == stamp_value) continue;
          if (!valid[g.value()]) return false;
          stamp[g.value()] = stamp_value;
          visited.push_back(g.value());
          next.push_back(g.value());
        }
      }
      frontier.swap(next);
    }
    return true;
  };
  for (uint32_t f = 0; f < n; ++f) {
    if (f % kFacesPerCancelCheck == 0 && IsCancelled(cancel)) return false;
    if (!valid[f] || !neighbourhood_valid(f)) continue;
    for (uint32_t g : visited) valid[g] = 0;
    seeds.push_back(f);
  }
  return true;
}

}  // namespace

MeshProblem MakeMeshProblem(const PreparedMesh& prepared, const MeshEnergyOptions& energy) {
  return {&prepared.mesh, &prepared.adjacency, &prepared.measures, energy};
}

absl::Status ValidateMeshProblem(const MeshProblem& problem) {
  if (problem.mesh == nullptr || problem.adjacency == nullptr || problem.measures == nullptr) {
    return absl::InvalidArgumentError("mesh problem without mesh, adjacency or measures");
  }
  if (problem.adjacency->num_faces() != problem.mesh->num_faces() ||
      problem.measures->num_faces() != problem.mesh->num_faces()) {
    return absl::InvalidArgumentError(
        absl::StrCat("adjacency (", problem.adjacency->num_faces(), " faces) or measures (",
                     problem.measures->num_faces(), " faces) do not match the mesh (",
                     problem.mesh->num_faces(), " faces)"));
  }
  return ValidateMeshEnergyOptions(problem.energy);
}

std::vector<uint32_t> LNeighbourhoodSeeds(const FaceAdjacency& adjacency, uint32_t level) {
  std::vector<uint32_t> seeds;
  LNeighbourhoodSeeds(adjacency, level, nullptr, seeds);
  return seeds;
}

absl::StatusOr<std::vector<ClusterId>> InitialClusters(const MeshProblem& problem,
                                                       const SeedOptions& options) {
  MLCLUST_RETURN_IF_ERROR(ValidateMeshProblem(problem));
  const FaceAdjacency& adjacency = *problem.adjacency;
  const size_t n = adjacency.num_faces();
  const uint32_t k = options.clusters;
  auto cancelled = [] { return absl::CancelledError("cancelled during initial clusters"); };
  if (k < 1 || k > n) {
    return absl::InvalidArgumentError(
        absl::StrCat("clusters: ", k, " must be between 1 and the mesh's ", n, " faces"));
  }
  std::vector<uint32_t> component;
  const uint32_t components = LabelFaceComponents(adjacency, component);
  if (k < components) {
    return absl::InvalidArgumentError(
        absl::StrCat("clusters: ", k, " is fewer than the mesh's ", components,
                     " connected components (a cluster cannot span two components)"));
  }
  if (IsCancelled(options.cancel)) return cancelled();
  std::vector<uint32_t> seeds;
  if (options.method == SeedOptions::Method::kRandom) {
    // One seed in every component, then the rest uniformly among the other faces.
    Random random(options.seed);
    std::vector<std::vector<uint32_t>> faces_of(components);
    for (uint32_t f = 0; f < n; ++f) faces_of[component[f]].push_back(f);
    std::vector<uint8_t> chosen(n, 0);
    for (const auto& faces : faces_of) {
      const uint32_t f = faces[random.Below(faces.size())];
      chosen[f] = 1;
      seeds.push_back(f);
    }
    // Partial Fisher-Yates over the faces not chosen yet.
    std::vector<uint32_t> pool;
    pool.reserve(n - seeds.size());
    for (uint32_t f = 0; f < n; ++f) {
      if (!chosen[f]) pool.push_back(f);
    }
    for (size_t i = 0; seeds.size() < k; ++i) {
      const size_t j = i + random.Below(pool.size() - i);
      std::swap(pool[i], pool[j]);
      seeds.push_back(pool[i]);
    }
  } else {
    uint32_t level = options.level;
    if (level == 0) {
      // The largest l that still gives k seeds: grow l by doubling, then bisect.
      uint32_t good = 0, bad = 0;
      for (uint32_t l = 1;; l *= 2) {
        if (!LNeighbourhoodSeeds(adjacency, l, options.cancel, seeds)) return cancelled();
        if (seeds.size() >= k) {
          good = l;
        } else {
          bad = l;
          break;
        }
        if (l > n) break;
      }
      while (bad > good + 1) {
        const uint32_t mid = good + (bad - good) / 2;
        if (!LNeighbourhoodSeeds(adjacency, mid, options.cancel, seeds)) return cancelled();
        (seeds.size() >= k ? good : bad) = mid;
      }
      level = good;
    }
    if (!LNeighbourhoodSeeds(adjacency, level, options.cancel, seeds)) return cancelled();
    if (seeds.size() < k) {
      return absl::InvalidArgumentError(absl::StrCat(
          "level: l = ", level, " gives only ", seeds.size(), " seeds, fewer than the ", k,
          " clusters asked for; use a smaller level (or 0 to choose it)"));
    }
  }
  // The CVD family grows by distance (each seed's centroid): geodesic Voronoi regions are
  // compact discs, which the connectivity guard then keeps and coarsening needs. The
  // planar and sphere energies grow by their own proxies, as VSA does: regions follow
  // the shape's faces, and a feature may legitimately sit inside another region.
  std::vector<uint32_t> labels;
  if (problem.energy.kind == MeshEnergyKind::kPlanar) {
    labels =
        WithMeshEnergy(problem.energy, *problem.mesh, *problem.measures, [&](const auto& energy) {
          return GrowFromSeeds(energy, adjacency, seeds, options.cancel);
        });
  } else {
    labels = GrowFromSeeds(CvdEnergy(*problem.measures), adjacency, seeds, options.cancel);
  }
  if (labels.empty()) return cancelled();
  if (seeds.size() > k) {
    labels = ReduceToK(*problem.mesh, adjacency, *problem.measures, std::move(labels),
                       static_cast<uint32_t>(seeds.size()), k, options.cancel);
    if (labels.empty()) return cancelled();
  }
  return ToClusterIds(labels);
}

absl::StatusOr<OptimizeResult> OptimizeEmlo(const MeshProblem& problem,
                                            std::vector<ClusterId>& labels,
                                            const EmloOptions& options) {
  MLCLUST_RETURN_IF_ERROR(ValidateMeshProblem(problem));
  const size_t n = problem.mesh->num_faces();
  if (labels.size() != n) {
    return absl::InvalidArgumentError(
        absl::StrCat("labels: ", labels.size(), " for a mesh of ", n, " faces"));
  }
  const Renumbering<ClusterId> renumbered =
      RenumberByFirstAppearance(std::span<const ClusterId>(labels));
  const std::vector<uint32_t>& compact = renumbered.dense;
  const std::vector<ClusterId>& original = renumbered.original;
  const uint32_t k = renumbered.size();
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "EMLO set-up"));
  return WithMeshEnergy(
      problem.energy, *problem.mesh, *problem.measures,
      [&](const auto& energy) -> absl::StatusOr<OptimizeResult> {
        using Energy = std::decay_t<decltype(energy)>;
        Partition<Energy> partition(energy, compact, k);
        MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "EMLO set-up"));
        MLCLUST_ASSIGN_OR_RETURN(
            const ConnectivityGuard guard,
            ConnectivityGuard::Build(*problem.mesh, *problem.adjacency, options.cancel));
        OptimizeResult result;
        result.initial_energy = partition.TotalEnergy();
        const uint64_t max_moves = options.max_moves != 0 ? options.max_moves : 1000 * n;
        uint64_t since_report = 0;
        const uint64_t every = std::max<uint64_t>(1, options.progress_moves);
        detail::EmloScratch scratch;
        const std::vector<uint32_t> boundary = detail::BoundaryFaces(*problem.adjacency, partition);
        const detail::EmloCounters counters = detail::RunEmloOn(
            *problem.adjacency, options.connectivity_guard ? &guard : nullptr, partition, boundary,
            max_moves, scratch,
            [&](uint32_t, uint32_t, uint32_t) {
              if (options.on_progress && ++since_report == every) {
                since_report = 0;
                ++result.iterations;
                options.on_progress(result.moves + 1, partition.TotalEnergy());
              }
              ++result.moves;
            },
            [](uint32_t, uint32_t) {}, options.cancel);
        if (counters.cancelled) return absl::CancelledError("cancelled during EMLO");
        result.converged = !counters.hit_move_limit;
        result.energy = partition.TotalEnergy();
        if (options.on_progress) options.on_progress(result.moves, result.energy);
        WriteBack(partition.labels(), original, labels);
        return result;
      });
}

absl::StatusOr<OptimizeResult> OptimizeBoundaryBased(const MeshProblem& problem,
                                                     std::vector<ClusterId>& labels,
                                                     const BoundaryBasedOptions& options) {
  MLCLUST_RETURN_IF_ERROR(ValidateMeshProblem(problem));
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
  const std::vector<uint32_t>& compact = renumbered.dense;
  const std::vector<ClusterId>& original = renumbered.original;
  const uint32_t k = renumbered.size();
  const boundary_based::StageThreads threads(options.threads);
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "BB set-up"));
  auto run = [&](const auto& energy) -> absl::StatusOr<OptimizeResult> {
    using Energy = std::decay_t<decltype(energy)>;
    Partition<Energy> partition(energy, compact, k);
    MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "BB set-up"));
    MLCLUST_ASSIGN_OR_RETURN(
        const ConnectivityGuard guard,
        ConnectivityGuard::Build(*problem.mesh, *problem.adjacency, options.cancel));
    const boundary_based::CpuBoundaryDecider<Energy> decide(energy, *problem.adjacency, threads);
    MLCLUST_ASSIGN_OR_RETURN(
        OptimizeResult result,
        boundary_based::RunBoundaryBased(guard, partition, options, threads, decide));
    WriteBack(partition.labels(), original, labels);
    return result;
  };
  return WithMeshEnergy(problem.energy, *problem.mesh, *problem.measures, run);
}

}  // namespace mlclust
