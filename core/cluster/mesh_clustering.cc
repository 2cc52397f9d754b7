#include "core/cluster/mesh_clustering.h"

#include <algorithm>
#include <numeric>
#include <optional>
#include <queue>

#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"
#include "core/base/random.h"
#include "core/base/renumber.h"
#include "core/base/status_macros.h"
#include "core/cluster/boundary_based.h"
#include "core/cluster/detail/emlo_impl.h"
#include "core/cluster/detail/polygon_energy.h"
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
template <typename Energy, typename Adjacency>
std::vector<uint32_t> GrowFromSeeds(const Energy& energy, const Adjacency& adjacency,
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

// The initial cluster grow of l. 671 and l. 1219: no energy; in rounds, every cluster in
// seed order takes the free faces across its boundary (the faces it took last round are
// its boundary's inner side). Empty if `cancel` was seen set.
//
// This is also section 5.2's growth (Fig. 5.9, SeedOptions::Growth::kRounds: each round
// every free face next to clusters joins the one with the smallest id, reading the
// labels before the round): a face still free after round r - 1 has neighbours in
// clusters only from round r - 1 (an older one would have taken it), and the first
// cluster in seed order whose last-round faces touch it is the smallest such id. So the
// CPU runs kRounds here; the GPU (gpu/kernels/seed_growth.h) runs the rule as written,
// and tests/gpu/stages/seed_growth_gpu_test.cc checks both against a full sweep per round.
template <typename Adjacency>
std::vector<uint32_t> GrowEnergyFree(const Adjacency& adjacency, std::span<const uint32_t> seeds,
                                     const std::atomic<bool>* cancel) {
  std::vector<uint32_t> labels(adjacency.num_faces(), kUnassigned);
  std::vector<std::vector<uint32_t>> frontier(seeds.size());
  for (uint32_t c = 0; c < seeds.size(); ++c) {
    labels[seeds[c]] = c;
    frontier[c].push_back(seeds[c]);
  }
  std::vector<uint32_t> taken;
  uint32_t until_cancel_check = kFacesPerCancelCheck;
  for (bool grew = true; grew;) {
    grew = false;
    for (uint32_t c = 0; c < seeds.size(); ++c) {
      taken.clear();
      for (uint32_t f : frontier[c]) {
        for (FaceId g : adjacency.neighbours[f]) {
          if (!g.valid() || labels[g.value()] != kUnassigned) continue;
          labels[g.value()] = c;
          taken.push_back(g.value());
          if (--until_cancel_check == 0) {
            until_cancel_check = kFacesPerCancelCheck;
            if (IsCancelled(cancel)) return {};
          }
        }
      }
      frontier[c].swap(taken);
      grew = grew || !frontier[c].empty();
    }
  }
  return labels;
}

// Grows `seeds` as `growth` says. The flood of the CVD family goes by distance (each
// seed's centroid): geodesic Voronoi regions are compact discs, which the connectivity
// guard then keeps and coarsening needs. The planar and sphere energies flood by their
// own proxies, as VSA does: regions follow the shape's faces, and a feature may
// legitimately sit inside another region. kRounds grows on the device where `device` is
// set (SeedOptions::device_rounds). Empty if `cancel` was seen set or the device failed
// (its error in *device_error).
std::vector<uint32_t> Grow(const MeshProblem& problem, std::span<const uint32_t> seeds,
                           SeedOptions::Growth growth, const std::atomic<bool>* cancel,
                           const SeedOptions::DeviceGrowth* device = nullptr,
                           absl::Status* device_error = nullptr) {
  const bool on_device = device != nullptr && *device;
  if (growth == SeedOptions::Growth::kEnergyFree ||
      (growth == SeedOptions::Growth::kRounds && !on_device)) {
    return GrowEnergyFree(*problem.adjacency, seeds, cancel);  // kRounds' partition too
  }
  if (growth == SeedOptions::Growth::kRounds) {
    absl::StatusOr<std::vector<uint32_t>> grown = (*device)(*problem.adjacency, seeds, cancel);
    if (!grown.ok()) {
      if (device_error != nullptr) *device_error = grown.status();
      return {};
    }
    return *std::move(grown);
  }
  if (problem.energy.kind == MeshEnergyKind::kPlanar) {
    return WithMeshEnergy(problem.energy, *problem.mesh, *problem.measures,
                          [&](const auto& energy) {
                            return GrowFromSeeds(energy, *problem.adjacency, seeds, cancel);
                          });
  }
  return GrowFromSeeds(CvdEnergy(*problem.measures), *problem.adjacency, seeds, cancel);
}

// Section 3.1.5: merge the three clusters meeting at a vertex with the smallest summed
// area until `target` clusters are left (a pair across an edge for the last step when the
// parity needs it). Returns labels renumbered 0..target-1. With `seed_faces` (in: the seed
// face of each of the `clusters` clusters) also the seed of each cluster left, in the new
// numbering: l. 849's "the seed's new position is assigned to the common vertex of the
// three original clusters" (the first face around that vertex; for a pair, the face whose
// edge joined them).
// Empty if `cancel` was seen set.
//
// Over any elements (faces, or polygons with problem.polygons): `element_area` and
// `labels` one per element, `element_of_face(f)` the element of face f and
// `for_each_vertex(e, fn)` fn(v) for the vertices of element e; seeds are elements.
template <typename Adjacency, typename ElementOfFace, typename ForEachVertex>
std::vector<uint32_t> ReduceToK(const TriangleMesh& mesh, const Adjacency& adjacency,
                                std::span<const double> element_area,
                                const ElementOfFace& element_of_face,
                                const ForEachVertex& for_each_vertex, std::vector<uint32_t> labels,
                                uint32_t clusters, uint32_t target, const std::atomic<bool>* cancel,
                                std::vector<uint32_t>* seed_faces = nullptr) {
  std::vector<uint32_t> parent(clusters);
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](uint32_t c) {
    while (parent[c] != c) c = parent[c] = parent[parent[c]];
    return c;
  };
  std::vector<double> area(clusters, 0.0);
  std::vector<std::vector<uint32_t>> members(clusters);
  for (uint32_t f = 0; f < labels.size(); ++f) {
    area[labels[f]] += element_area[f];
    members[labels[f]].push_back(f);
  }
  // Distinct clusters around each vertex, from its faces.
  const size_t num_vertices = mesh.num_vertices();
  const VertexFaceTable table = BuildVertexFaceTable(mesh);
  auto clusters_at = [&](uint32_t v, uint32_t out[4]) {
    int count = 0;
    for (uint32_t face : table.faces_around(v)) {
      if (count == 4) break;
      const uint32_t c = find(labels[element_of_face(face)]);
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
    if (seed_faces != nullptr) (*seed_faces)[keep] = element_of_face(table.faces_around(v)[0]);
    count -= 2;
    for (uint32_t f : members[keep]) for_each_vertex(f, consider);
  }
  // Pairs: the last step for parity, or all steps where no vertex joins three clusters.
  while (count > target) {
    if (IsCancelled(cancel)) return {};  // each step scans every face
    double best = std::numeric_limits<double>::infinity();
    uint32_t best_a = 0, best_b = 0, best_face = 0;
    for (uint32_t f = 0; f < labels.size(); ++f) {
      for (FaceId g : adjacency.neighbours[f]) {
        if (!g.valid()) continue;
        const uint32_t a = find(labels[f]), b = find(labels[g.value()]);
        if (a != b && area[a] + area[b] < best) {
          best = area[a] + area[b];
          best_a = a;
          best_b = b;
          best_face = f;
        }
      }
    }
    if (best == std::numeric_limits<double>::infinity()) break;
    const uint32_t keep = merge_into(best_a, best_b);
    if (seed_faces != nullptr) (*seed_faces)[keep] = best_face;
    --count;
  }
  for (uint32_t& l : labels) l = find(l);
  Renumbering<uint32_t> renumbered = RenumberByFirstAppearance(std::span<const uint32_t>(labels));
  if (seed_faces != nullptr) {
    std::vector<uint32_t> kept(renumbered.size());
    for (uint32_t c = 0; c < renumbered.size(); ++c)
      kept[c] = (*seed_faces)[renumbered.original[c]];
    seed_faces->swap(kept);
  }
  return std::move(renumbered.dense);
}

// l. 849's seed-adding variant: from `seeds` (fewer than `target`), grow; add seeds at
// the vertices where three clusters meet, largest summed area first, each cluster taking
// part in one new seed per round; grow again; until `target` seeds. A round that finds no
// such vertex adds one seed in the largest cluster, at the face farthest in edge steps
// from its seed. Returns the final growth's labels; empty if `cancel` was seen set.
std::vector<uint32_t> AddSeedsAndGrow(const MeshProblem& problem, std::vector<uint32_t> seeds,
                                      uint32_t target, SeedOptions::Growth growth,
                                      const std::atomic<bool>* cancel,
                                      const SeedOptions::DeviceGrowth* device = nullptr,
                                      absl::Status* device_error = nullptr) {
  const TriangleMesh& mesh = *problem.mesh;
  const FaceAdjacency& adjacency = *problem.adjacency;
  const VertexFaceTable table = BuildVertexFaceTable(mesh);
  std::vector<uint8_t> is_seed(adjacency.num_faces(), 0);
  for (uint32_t f : seeds) is_seed[f] = 1;
  std::vector<uint32_t> labels = Grow(problem, seeds, growth, cancel, device, device_error);
  while (!labels.empty() && seeds.size() < target) {
    const uint32_t clusters = static_cast<uint32_t>(seeds.size());
    std::vector<double> area(clusters, 0.0);
    for (uint32_t f = 0; f < labels.size(); ++f) area[labels[f]] += problem.measures->area[f];
    struct Candidate {
      double area;
      uint32_t vertex;
      uint32_t clusters[3];
    };
    std::vector<Candidate> candidates;
    for (uint32_t v = 0; v < mesh.num_vertices(); ++v) {
      uint32_t around[4];
      int count = 0;
      for (uint32_t face : table.faces_around(v)) {
        if (count == 4) break;
        if (std::find(around, around + count, labels[face]) == around + count) {
          around[count++] = labels[face];
        }
      }
      if (count != 3) continue;
      candidates.push_back({area[around[0]] + area[around[1]] + area[around[2]],
                            v,
                            {around[0], around[1], around[2]}});
    }
    if (IsCancelled(cancel)) return {};
    std::stable_sort(candidates.begin(), candidates.end(),
                     [](const Candidate& a, const Candidate& b) { return a.area > b.area; });
    std::vector<uint8_t> used(clusters, 0);
    for (const Candidate& candidate : candidates) {
      if (seeds.size() == target) break;
      const uint32_t* c = candidate.clusters;
      if (used[c[0]] || used[c[1]] || used[c[2]]) continue;
      for (uint32_t face : table.faces_around(candidate.vertex)) {
        if (is_seed[face]) continue;
        is_seed[face] = 1;
        seeds.push_back(face);
        used[c[0]] = used[c[1]] = used[c[2]] = 1;
        break;
      }
    }
    if (seeds.size() == clusters) {
      // No vertex joins three clusters: in the cluster with the most faces (so that it has
      // a face to spare while there are fewer seeds than faces), the face farthest from its
      // seed.
      std::vector<uint32_t> faces_in(clusters, 0);
      for (uint32_t label : labels) ++faces_in[label];
      const uint32_t largest = static_cast<uint32_t>(
          std::max_element(faces_in.begin(), faces_in.end()) - faces_in.begin());
      std::vector<uint32_t> queue = {seeds[largest]};
      std::vector<uint8_t> seen(adjacency.num_faces(), 0);
      seen[seeds[largest]] = 1;
      for (size_t i = 0; i < queue.size(); ++i) {
        for (FaceId g : adjacency.neighbours[queue[i]]) {
          if (g.valid() && !seen[g.value()] && labels[g.value()] == largest) {
            seen[g.value()] = 1;
            queue.push_back(g.value());
          }
        }
      }
      if (is_seed[queue.back()]) break;  // every cluster one face: seeds == faces >= k
      is_seed[queue.back()] = 1;
      seeds.push_back(queue.back());
    }
    labels = Grow(problem, seeds, growth, cancel, device, device_error);
  }
  return labels;
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

// Alg. 3.1 (over faces, or polygons); false (and `seeds` unspecified) if `cancel` was seen
// set.
template <typename Adjacency>
bool LNeighbourhoodSeeds(const Adjacency& adjacency, uint32_t level,
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

namespace {

// The faces as InitialElementClusters' elements.
struct TriangleElements {
  const MeshProblem& problem;
  const SeedOptions& options;
  // The device growth's error (SeedOptions::device_rounds), if it failed.
  mutable absl::Status device_error = absl::OkStatus();
  const FaceAdjacency& adjacency() const { return *problem.adjacency; }
  const char* noun() const { return "faces"; }
  uint32_t Components(std::vector<uint32_t>& component) const {
    return LabelFaceComponents(*problem.adjacency, component);
  }
  bool Seeds(uint32_t level, std::vector<uint32_t>& seeds) const {
    return LNeighbourhoodSeeds(*problem.adjacency, level, options.cancel, seeds);
  }
  std::vector<uint32_t> Grow(std::span<const uint32_t> seeds) const {
    return mlclust::Grow(problem, seeds, options.growth, options.cancel, &options.device_rounds,
                         &device_error);
  }
  std::vector<uint32_t> Reduce(std::vector<uint32_t> labels, uint32_t clusters, uint32_t target,
                               std::vector<uint32_t>* seeds) const {
    return ReduceToK(
        *problem.mesh, *problem.adjacency, problem.measures->area, [](uint32_t f) { return f; },
        [&](uint32_t f, const auto& fn) {
          for (int c = 0; c < 3; ++c) fn(problem.mesh->indices[3 * size_t{f} + c]);
        },
        std::move(labels), clusters, target, options.cancel, seeds);
  }
  std::vector<uint32_t> AddSeedsAndGrow(std::vector<uint32_t> seeds, uint32_t target) const {
    return mlclust::AddSeedsAndGrow(problem, std::move(seeds), target, options.growth,
                                    options.cancel, &options.device_rounds, &device_error);
  }
};

// The polygons (problem.polygons) as InitialElementClusters' elements: growth with the
// polygon energy on the polygons' dual graph, and the reduction's vertices those of a
// polygon's triangles. Alg. 3.1 runs on the triangles (l counts triangle edge steps) and
// each seed moves to its polygon, a polygon seeded twice counting once: ours, since on the
// dual graph of a coarse polygon mesh the seeds' neighbourhoods are too coarse (on CGAL's
// double torus at K = 50 the grown seeds had 4x the energy of the triangles' seeds moved
// to polygons; BENCHMARKS.md). No seed adding (refused before).
struct PolygonElements {
  const MeshProblem& problem;
  const SeedOptions& options;
  std::vector<double> area;  // per polygon

  PolygonElements(const MeshProblem& p, const SeedOptions& o)
      : problem(p), options(o), area(p.polygons->num_polygons(), 0.0) {
    for (size_t f = 0; f < p.polygons->num_faces(); ++f) {
      area[p.polygons->polygon_of_face[f]] += p.measures->area[f];
    }
  }
  const PolygonAdjacency& adjacency() const { return problem.polygons->adjacency; }
  const char* noun() const { return "polygons"; }
  bool Seeds(uint32_t level, std::vector<uint32_t>& seeds) const {
    std::vector<uint32_t> faces;
    if (!LNeighbourhoodSeeds(*problem.adjacency, level, options.cancel, faces)) return false;
    seeds.clear();
    std::vector<uint8_t> seeded(problem.polygons->num_polygons(), 0);
    for (uint32_t f : faces) {
      const uint32_t p = problem.polygons->polygon_of_face[f];
      if (!seeded[p]) {
        seeded[p] = 1;
        seeds.push_back(p);
      }
    }
    return true;
  }
  // A polygon is edge-connected: its component is its first triangle's.
  uint32_t Components(std::vector<uint32_t>& component) const {
    std::vector<uint32_t> of_face;
    const uint32_t count = LabelFaceComponents(*problem.adjacency, of_face);
    const MeshPolygons& polygons = *problem.polygons;
    component.resize(polygons.num_polygons());
    for (size_t p = 0; p < component.size(); ++p) {
      component[p] = of_face[polygons.first_face[p]];
    }
    return count;
  }
  std::vector<uint32_t> Grow(std::span<const uint32_t> seeds) const {
    const PolygonAdjacency& graph = problem.polygons->adjacency;
    if (options.growth == SeedOptions::Growth::kEnergyFree ||
        options.growth == SeedOptions::Growth::kRounds) {  // the same partition; no device
      return GrowEnergyFree(graph, seeds, options.cancel);
    }
    if (problem.energy.kind == MeshEnergyKind::kPlanar) {
      return WithMeshEnergy(problem.energy, *problem.mesh, *problem.measures,
                            [&](const auto& triangles) {
                              const detail::PolygonEnergy energy(triangles, *problem.polygons);
                              return GrowFromSeeds(energy, graph, seeds, options.cancel);
                            });
    }
    const CvdEnergy triangles(*problem.measures);
    return GrowFromSeeds(detail::PolygonEnergy(triangles, *problem.polygons), graph, seeds,
                         options.cancel);
  }
  std::vector<uint32_t> Reduce(std::vector<uint32_t> labels, uint32_t clusters, uint32_t target,
                               std::vector<uint32_t>* seeds) const {
    const MeshPolygons& polygons = *problem.polygons;
    return ReduceToK(
        *problem.mesh, polygons.adjacency, area,
        [&](uint32_t f) { return polygons.polygon_of_face[f]; },
        [&](uint32_t p, const auto& fn) {
          for (uint32_t f = polygons.first_face[p]; f < polygons.first_face[p + 1]; ++f) {
            for (int c = 0; c < 3; ++c) fn(problem.mesh->indices[3 * size_t{f} + c]);
          }
        },
        std::move(labels), clusters, target, options.cancel, seeds);
  }
  std::vector<uint32_t> AddSeedsAndGrow(std::vector<uint32_t> /*seeds*/,
                                        uint32_t /*target*/) const {
    return {};  // refused in InitialClusters
  }
  absl::Status device_error = absl::OkStatus();  // polygons never grow on a device
};

// InitialClusters over `elements`: faces (TriangleElements) or polygons (PolygonElements),
// each giving its adjacency(), a noun for messages, the elements' connected components,
// Seeds(l, seeds) (Alg. 3.1; false if cancelled), Grow(seeds), Reduce(labels, clusters,
// target, seeds or null) and AddSeedsAndGrow(seeds, target). Labels are per element.
template <typename Elements>
absl::StatusOr<std::vector<uint32_t>> InitialElementClusters(const Elements& elements,
                                                             const SeedOptions& options) {
  const auto& adjacency = elements.adjacency();
  const size_t n = adjacency.num_faces();
  const uint32_t k = options.clusters;
  // Empty labels: cancelled, or the device growth's error.
  auto cancelled = [&elements]() -> absl::Status {
    if (!elements.device_error.ok()) return elements.device_error;
    return absl::CancelledError("cancelled during initial clusters");
  };
  if (k < 1 || k > n) {
    return absl::InvalidArgumentError(absl::StrCat(
        "clusters: ", k, " must be between 1 and the mesh's ", n, " ", elements.noun()));
  }
  std::vector<uint32_t> component;
  const uint32_t components = elements.Components(component);
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
        if (!elements.Seeds(l, seeds)) return cancelled();
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
        if (!elements.Seeds(mid, seeds)) return cancelled();
        (seeds.size() >= k ? good : bad) = mid;
      }
      level = good;
    }
    if (!elements.Seeds(level, seeds)) return cancelled();
    if (seeds.size() < k && !options.add_seeds) {
      return absl::InvalidArgumentError(absl::StrCat(
          "level: l = ", level, " gives only ", seeds.size(), " seeds, fewer than the ", k,
          " clusters asked for; use a smaller level (or 0 to choose it), or add-seeds"));
    }
  }
  std::vector<uint32_t> labels;
  if (seeds.size() < k) {
    labels = elements.AddSeedsAndGrow(std::move(seeds), k);
    if (labels.empty()) return cancelled();
  } else {
    labels = elements.Grow(seeds);
    if (labels.empty()) return cancelled();
    if (seeds.size() > k) {
      const bool reseed = options.reduction == SeedOptions::Reduction::kReseedAndRegrow;
      labels = elements.Reduce(std::move(labels), static_cast<uint32_t>(seeds.size()), k,
                               reseed ? &seeds : nullptr);
      if (labels.empty()) return cancelled();
      if (reseed) {
        labels = elements.Grow(seeds);
        if (labels.empty()) return cancelled();
      }
    }
  }
  return labels;
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
  if (problem.polygons != nullptr &&
      (problem.polygons->num_faces() != problem.mesh->num_faces() ||
       problem.polygons->adjacency.num_faces() != problem.polygons->num_polygons())) {
    return absl::InvalidArgumentError(absl::StrCat("polygons of ", problem.polygons->num_faces(),
                                                   " faces for a mesh of ",
                                                   problem.mesh->num_faces(), " faces"));
  }
  return ValidateMeshEnergyOptions(problem.energy);
}

std::vector<FaceId> LNeighbourhoodSeeds(const FaceAdjacency& adjacency, uint32_t level) {
  std::vector<uint32_t> seeds;
  LNeighbourhoodSeeds(adjacency, level, nullptr, seeds);
  return std::vector<FaceId>(seeds.begin(), seeds.end());
}

absl::StatusOr<std::vector<ClusterId>> InitialClusters(const MeshProblem& problem,
                                                       const SeedOptions& options) {
  MLCLUST_RETURN_IF_ERROR(ValidateMeshProblem(problem));
  if (problem.polygons == nullptr) {
    MLCLUST_ASSIGN_OR_RETURN(std::vector<uint32_t> labels,
                             InitialElementClusters(TriangleElements{problem, options}, options));
    return ToClusterIds(labels);
  }
  if (options.add_seeds) {
    return absl::InvalidArgumentError(
        "add-seeds: l. 849's seed adding is per triangle and not available with polygons");
  }
  MLCLUST_ASSIGN_OR_RETURN(std::vector<uint32_t> labels,
                           InitialElementClusters(PolygonElements(problem, options), options));
  return FaceLabelsOfPolygons(*problem.polygons, labels);
}

absl::Status CheckSeedFaces(size_t num_faces, std::span<const uint32_t> seeds) {
  std::vector<uint8_t> is_seed(num_faces, 0);
  for (size_t i = 0; i < seeds.size(); ++i) {
    if (seeds[i] >= num_faces || is_seed[seeds[i]]) {
      return absl::InvalidArgumentError(
          absl::StrCat("seeds: seed ", i, " (face ", seeds[i], ") is out of range or repeated"));
    }
    is_seed[seeds[i]] = 1;
  }
  return absl::OkStatus();
}

absl::StatusOr<std::vector<ClusterId>> GrowClustersFromSeeds(
    const MeshProblem& problem, std::span<const FaceId> typed_seeds, SeedOptions::Growth growth,
    const std::atomic<bool>* cancel, const SeedOptions::DeviceGrowth* device) {
  MLCLUST_RETURN_IF_ERROR(ValidateMeshProblem(problem));
  const size_t n = problem.mesh->num_faces();
  std::vector<uint32_t> seeds(typed_seeds.size());
  for (size_t i = 0; i < seeds.size(); ++i) seeds[i] = typed_seeds[i].value();
  MLCLUST_RETURN_IF_ERROR(CheckSeedFaces(n, seeds));
  if (problem.polygons != nullptr) {
    // Each seed face's polygon; two seeds in one polygon are one seed too many.
    const MeshPolygons& polygons = *problem.polygons;
    std::vector<uint8_t> seeded(polygons.num_polygons(), 0);
    for (size_t i = 0; i < seeds.size(); ++i) {
      seeds[i] = polygons.polygon_of_face[seeds[i]];
      if (seeded[seeds[i]]) {
        return absl::InvalidArgumentError(absl::StrCat("seeds: seed ", i, " (face ",
                                                       typed_seeds[i].value(), ") is in polygon ",
                                                       seeds[i], ", which has a seed already"));
      }
      seeded[seeds[i]] = 1;
    }
    SeedOptions options;
    options.growth = growth;
    options.cancel = cancel;
    const std::vector<uint32_t> polygon_labels = PolygonElements(problem, options).Grow(seeds);
    if (polygon_labels.empty()) return absl::CancelledError("cancelled while growing seeds");
    for (uint32_t p = 0; p < polygon_labels.size(); ++p) {
      if (polygon_labels[p] == kUnassigned) {
        return absl::InvalidArgumentError(
            absl::StrCat("seeds: polygon ", p, "'s connected component has no seed"));
      }
    }
    return FaceLabelsOfPolygons(polygons, polygon_labels);
  }
  absl::Status device_error = absl::OkStatus();
  std::vector<uint32_t> labels = Grow(problem, seeds, growth, cancel, device, &device_error);
  MLCLUST_RETURN_IF_ERROR(device_error);
  if (labels.empty() && n != 0) return absl::CancelledError("cancelled while growing seeds");
  for (uint32_t f = 0; f < n; ++f) {
    if (labels[f] == kUnassigned) {
      return absl::InvalidArgumentError(
          absl::StrCat("seeds: face ", f, "'s connected component has no seed"));
    }
  }
  return ToClusterIds(labels);
}

namespace {

// Alg. 3.2's counts are kept per triangle edge: refused with polygons.
absl::Status CheckPolygonGuard(const MeshProblem& problem, bool connectivity_guard,
                               ConnectivityGuardKind guard) {
  if (problem.polygons != nullptr && connectivity_guard &&
      guard == ConnectivityGuardKind::kVertexBoundaryEdgeCount) {
    return absl::InvalidArgumentError(
        "guard: Alg. 3.2's vertex boundary-edge counts are per triangle; with polygons use the "
        "ring test (or none)");
  }
  return absl::OkStatus();
}

// Labels per polygon, renumbered 0..k-1 by first appearance.
absl::StatusOr<Renumbering<ClusterId>> CompactPolygonLabels(const MeshProblem& problem,
                                                            std::span<const ClusterId> labels) {
  MLCLUST_ASSIGN_OR_RETURN(const std::vector<ClusterId> polygon_labels,
                           PolygonLabelsOfFaces(*problem.polygons, labels));
  return RenumberByFirstAppearance(std::span<const ClusterId>(polygon_labels));
}

// OptimizeEmlo with problem.polygons: EMLO over the polygons (their sums, their dual graph,
// the polygons' ring test).
absl::StatusOr<OptimizeResult> OptimizeEmloOnPolygons(const MeshProblem& problem,
                                                      std::vector<ClusterId>& labels,
                                                      const EmloOptions& options) {
  MLCLUST_RETURN_IF_ERROR(CheckPolygonGuard(problem, options.connectivity_guard, options.guard));
  const MeshPolygons& polygons = *problem.polygons;
  MLCLUST_ASSIGN_OR_RETURN(const Renumbering<ClusterId> renumbered,
                           CompactPolygonLabels(problem, labels));
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "EMLO set-up"));
  std::optional<ConnectivityGuard> rings;
  if (options.connectivity_guard && options.guard != ConnectivityGuardKind::kOff) {
    MLCLUST_ASSIGN_OR_RETURN(
        ConnectivityGuard built,
        BuildPolygonConnectivityGuard(*problem.mesh, *problem.adjacency, polygons, options.cancel));
    rings.emplace(std::move(built));
  }
  return WithMeshEnergy(
      problem.energy, *problem.mesh, *problem.measures,
      [&](const auto& triangles) -> absl::StatusOr<OptimizeResult> {
        const detail::PolygonEnergy energy(triangles, polygons);
        Partition partition(energy, renumbered.dense, renumbered.size());
        OptimizeResult result;
        result.initial_energy = partition.TotalEnergy();
        const uint64_t max_moves =
            options.max_moves != 0 ? options.max_moves : 1000 * polygons.num_polygons();
        uint64_t since_report = 0;
        const uint64_t every = std::max<uint64_t>(1, options.progress_moves);
        detail::EmloScratch scratch;
        const std::vector<uint32_t> boundary = detail::BoundaryFaces(polygons.adjacency, partition);
        auto on_move = [&](uint32_t, uint32_t, uint32_t) {
          if (options.on_progress && ++since_report == every) {
            since_report = 0;
            ++result.iterations;
            options.on_progress(result.moves + 1, partition.TotalEnergy());
          }
          ++result.moves;
        };
        const detail::EmloCounters counters = detail::RunEmloOn(
            polygons.adjacency, rings.has_value() ? &*rings : nullptr, partition, boundary,
            max_moves, scratch, on_move, [](uint32_t, uint32_t) {}, options.cancel);
        if (counters.cancelled) return absl::CancelledError("cancelled during EMLO");
        result.converged = !counters.hit_move_limit;
        partition.RefreshAllSums();  // the energy of the labels, not of sums worn by moves
        result.energy = partition.TotalEnergy();
        if (options.on_progress) options.on_progress(result.moves, result.energy);
        for (size_t f = 0; f < labels.size(); ++f) {
          labels[f] = renumbered.original[partition.label(polygons.polygon_of_face[f])];
        }
        return result;
      });
}

// OptimizeBoundaryBased with problem.polygons: the stages over the polygons, with the CPU
// decide stage.
absl::StatusOr<OptimizeResult> OptimizeBoundaryBasedOnPolygons(
    const MeshProblem& problem, std::vector<ClusterId>& labels,
    const BoundaryBasedOptions& options) {
  MLCLUST_RETURN_IF_ERROR(CheckPolygonGuard(problem, options.connectivity_guard, options.guard));
  if (options.threads < 0) {
    return absl::InvalidArgumentError(absl::StrCat("threads: ", options.threads, " < 0"));
  }
  const MeshPolygons& polygons = *problem.polygons;
  MLCLUST_ASSIGN_OR_RETURN(const Renumbering<ClusterId> renumbered,
                           CompactPolygonLabels(problem, labels));
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "BB set-up"));
  // The ring structure always: the conflict rule reads it whatever the guard.
  MLCLUST_ASSIGN_OR_RETURN(
      const ConnectivityGuard rings,
      BuildPolygonConnectivityGuard(*problem.mesh, *problem.adjacency, polygons, options.cancel));
  const boundary_based::StageThreads threads(options.threads);
  return WithMeshEnergy(
      problem.energy, *problem.mesh, *problem.measures,
      [&](const auto& triangles) -> absl::StatusOr<OptimizeResult> {
        using Energy = detail::PolygonEnergy<std::decay_t<decltype(triangles)>>;
        const Energy energy(triangles, polygons);
        Partition partition(energy, renumbered.dense, renumbered.size());
        const boundary_based::CpuBoundaryDecider<Energy, PolygonAdjacency> decide(
            energy, polygons.adjacency, threads);
        MLCLUST_ASSIGN_OR_RETURN(
            OptimizeResult result,
            boundary_based::RunBoundaryBased(rings, partition, options, threads, decide));
        for (size_t f = 0; f < labels.size(); ++f) {
          labels[f] = renumbered.original[partition.label(polygons.polygon_of_face[f])];
        }
        return result;
      });
}

}  // namespace

absl::StatusOr<OptimizeResult> OptimizeEmlo(const MeshProblem& problem,
                                            std::vector<ClusterId>& labels,
                                            const EmloOptions& options) {
  MLCLUST_RETURN_IF_ERROR(ValidateMeshProblem(problem));
  if (labels.size() != problem.mesh->num_faces()) {
    return absl::InvalidArgumentError(absl::StrCat("labels: ", labels.size(), " for a mesh of ",
                                                   problem.mesh->num_faces(), " faces"));
  }
  if (problem.polygons != nullptr) return OptimizeEmloOnPolygons(problem, labels, options);
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
        const ConnectivityGuardKind kind =
            options.connectivity_guard ? options.guard : ConnectivityGuardKind::kOff;
        std::optional<ConnectivityGuard> rings;
        std::optional<VertexBoundaryEdgeCountGuard> counts;
        if (kind == ConnectivityGuardKind::kRingTest) {
          MLCLUST_ASSIGN_OR_RETURN(
              ConnectivityGuard built,
              ConnectivityGuard::Build(*problem.mesh, *problem.adjacency, options.cancel));
          rings.emplace(std::move(built));
        } else if (kind == ConnectivityGuardKind::kVertexBoundaryEdgeCount) {
          // Alg. 3.2: counts set from the start's boundary edges, then updated per move.
          counts.emplace(*problem.mesh, *problem.adjacency);
          counts->Reset(partition.labels());
        }
        OptimizeResult result;
        result.initial_energy = partition.TotalEnergy();
        const uint64_t max_moves = options.max_moves != 0 ? options.max_moves : 1000 * n;
        uint64_t since_report = 0;
        const uint64_t every = std::max<uint64_t>(1, options.progress_moves);
        detail::EmloScratch scratch;
        const std::vector<uint32_t> boundary = detail::BoundaryFaces(*problem.adjacency, partition);
        auto on_move = [&](uint32_t face, uint32_t from, uint32_t) {
          if (counts.has_value()) counts->OnMove(face, from, partition.labels());
          if (options.on_progress && ++since_report == every) {
            since_report = 0;
            ++result.iterations;
            options.on_progress(result.moves + 1, partition.TotalEnergy());
          }
          ++result.moves;
        };
        const detail::EmloCounters counters =
            counts.has_value() ? detail::RunEmloOn(
                                     *problem.adjacency, &*counts, partition, boundary, max_moves,
                                     scratch, on_move, [](uint32_t, uint32_t) {}, options.cancel)
                               : detail::RunEmloOn(
                                     *problem.adjacency, rings.has_value() ? &*rings : nullptr,
                                     partition, boundary, max_moves, scratch, on_move,
                                     [](uint32_t, uint32_t) {}, options.cancel);
        if (counters.cancelled) return absl::CancelledError("cancelled during EMLO");
        result.converged = !counters.hit_move_limit;
        partition.RefreshAllSums();  // the energy of the labels, not of sums worn by moves
        result.energy = partition.TotalEnergy();
        if (options.on_progress) options.on_progress(result.moves, result.energy);
        WriteBack(partition.labels(), original, labels);
        return result;
      });
}

absl::StatusOr<OptimizeResult> OptimizeBoundaryBased(const MeshProblem& problem,
                                                     std::vector<ClusterId>& labels,
                                                     const BoundaryBasedOptions& options) {
  if (problem.polygons != nullptr) {
    MLCLUST_RETURN_IF_ERROR(ValidateMeshProblem(problem));
    if (labels.size() != problem.mesh->num_faces()) {
      return absl::InvalidArgumentError(absl::StrCat("labels: ", labels.size(), " for a mesh of ",
                                                     problem.mesh->num_faces(), " faces"));
    }
    return OptimizeBoundaryBasedOnPolygons(problem, labels, options);
  }
  // The staged BB with the CPU's decide stage; a device backend passes its own.
  return boundary_based::OptimizeBoundaryBasedWith(
      problem, labels, options,
      [&](const auto& energy, uint32_t /*num_clusters*/,
          const boundary_based::StageThreads& threads)
          -> absl::StatusOr<boundary_based::CpuBoundaryDecider<std::decay_t<decltype(energy)>>> {
        return boundary_based::CpuBoundaryDecider<std::decay_t<decltype(energy)>>(
            energy, *problem.adjacency, threads);
      });
}

}  // namespace mlclust
