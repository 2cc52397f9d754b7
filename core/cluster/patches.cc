#include "core/cluster/patches.h"

#include <algorithm>
#include <array>
#include <limits>

#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"
#include "core/base/morton.h"
#include "core/base/status_macros.h"
#include "core/cluster/boundary_based.h"
#include "core/cluster/partition.h"
#include "core/mesh/connectivity_guard.h"
#include "core/mesh/mesh.h"

namespace mlclust {
namespace {

// Morton code of every face's centroid in the bounding box of the centroids: 10 bits per
// axis, interleaved (x lowest). The box's longest side sets one scale for all three axes,
// so cells are cubes and runs of the curve are compact in space.
std::vector<uint32_t> MortonCodes(const FaceMeasures& measures) {
  const size_t n = measures.num_faces();
  Vec3 low = measures.centroid[0], high = low;
  for (const Vec3& c : measures.centroid) {
    low = {std::min(low.x, c.x), std::min(low.y, c.y), std::min(low.z, c.z)};
    high = {std::max(high.x, c.x), std::max(high.y, c.y), std::max(high.z, c.z)};
  }
  const double extent = std::max({high.x - low.x, high.y - low.y, high.z - low.z});
  const double scale = extent > 0 ? 1023.0 / extent : 0.0;
  auto cell = [&](double value, double origin) {
    return static_cast<uint32_t>(std::clamp((value - origin) * scale, 0.0, 1023.0));
  };
  std::vector<uint32_t> codes(n);
  for (size_t f = 0; f < n; ++f) {
    const Vec3& c = measures.centroid[f];
    codes[f] = MortonCode(cell(c.x, low.x), cell(c.y, low.y), cell(c.z, low.z));
  }
  return codes;
}

// Faces sorted by (component, Morton code, face id): two stable 15-bit radix passes over
// the 30-bit codes, then a stable counting sort by component. O(faces), where a comparison
// sort of a million faces would cost more than the growth.
std::vector<uint32_t> FacesInMortonOrder(std::span<const uint32_t> codes,
                                         std::span<const uint32_t> component, uint32_t components) {
  const size_t n = codes.size();
  std::vector<uint32_t> order(n), next(n);
  for (uint32_t f = 0; f < n; ++f) order[f] = f;
  constexpr uint32_t kBits = 15;
  constexpr uint32_t kBuckets = 1u << kBits;
  std::vector<uint32_t> start(std::max(kBuckets, components) + 1);
  auto counting_pass = [&](auto key, uint32_t buckets) {
    std::fill(start.begin(), start.begin() + buckets + 1, 0);
    for (uint32_t f : order) ++start[key(f) + 1];
    for (uint32_t b = 0; b < buckets; ++b) start[b + 1] += start[b];
    for (uint32_t f : order) next[start[key(f)]++] = f;
    order.swap(next);
  };
  counting_pass([&](uint32_t f) { return codes[f] & (kBuckets - 1); }, kBuckets);
  counting_pass([&](uint32_t f) { return codes[f] >> kBits; }, kBuckets);
  if (components > 1) counting_pass([&](uint32_t f) { return component[f]; }, components);
  return order;
}

// ConnectivityGuard::CanMove's ring test with the ring built on demand into `ring`. (A walk
// that counts the runs as it goes, without storing the ring and without branches on the
// corner, measured no faster: the walk waits on memory, one face after the next.)
bool RingTest(const TriangleMesh& mesh, const FaceAdjacency& adjacency, uint32_t face, uint32_t to,
              std::span<const uint32_t> labels, std::vector<uint32_t>& ring) {
  BuildFaceRing(mesh, adjacency, face, ring);
  return RingTestAllows(ring, labels[face], to, labels);
}

struct SweepResult {
  double initial_energy = 0, energy = 0;
  uint32_t sweeps = 0;
  uint64_t moves = 0;
};

// Step 3: BB sweeps (Alg. 5.1) with proxies fixed per sweep and every face deciding on its
// own, in parallel (boundary_based::DecideBoundaryMove, the rule of the BB stages), with
// the ring test against the sweep's starting labels (the ring built on demand: no ring is
// built for a face that does not propose a move, where OptimizeBoundaryBased builds every
// face's ring first, about 0.3 s for a million faces, more than the rest of this route).
// What differs from OptimizeBoundaryBased is how proposals apply: in face order, each valid
// against the labels as they are by then (a face whose vertices no earlier move of the sweep
// touched has the ring its test saw; the others are tested again: the ring test and an edge
// neighbour still in the target), so no vertex-conflict rule is needed and neighbouring
// faces may move in the same sweep. Each move
// lowers the face's cost against the fixed proxies and refitting lowers it again, so for the
// CVD energies a sweep never raises the energy; a sweep that does (MWCVD, whose weights are
// not fitted) is undone and ends the run, as in BB.
template <typename Energy>
absl::StatusOr<SweepResult> Sweep(const MeshProblem& problem, const Energy& energy,
                                  std::vector<uint32_t>& labels, uint32_t clusters,
                                  const PatchOptions& options) {
  using boundary_based::kNoMove;
  const FaceAdjacency& adjacency = *problem.adjacency;
  const size_t n = labels.size();
  Partition<Energy> partition(energy, labels, clusters);
  const boundary_based::StageThreads threads(options.threads);
  const bool guard = options.guard != ConnectivityGuardKind::kOff;
  std::vector<typename Energy::Proxy> proxies;
  std::vector<uint32_t> target(n, kNoMove), ring;
  std::vector<boundary_based::AppliedMove> applied;
  // The last sweep that moved a face around each vertex (0: none).
  std::vector<uint32_t> vertex_moved(problem.mesh->num_vertices(), 0);
  SweepResult result;
  result.initial_energy = partition.TotalEnergy();
  double current = result.initial_energy;
  for (uint32_t sweep = 1; sweep <= options.sweeps; ++sweep) {
    MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "patch sweeps"));
    boundary_based::FitProxies(partition, proxies);
    const std::span<const uint32_t> now = partition.labels();
    // Decide, and for a proposal the ring test against the sweep's starting labels, in
    // parallel: the rings are the costly part.
    threads.ParallelFor(n, 4096, [&](size_t begin, size_t end) {
      std::vector<uint32_t> block_ring;
      for (size_t f = begin; f != end; ++f) {
        const uint32_t own = now[f];
        bool boundary = false;
        for (FaceId g : adjacency.neighbours[f]) boundary |= g.valid() && now[g.value()] != own;
        uint32_t to =
            boundary ? boundary_based::DecideBoundaryMove(
                           energy, adjacency, now, std::span<const typename Energy::Proxy>(proxies),
                           static_cast<uint32_t>(f))
                     : kNoMove;
        if (to != kNoMove && guard &&
            !RingTest(*problem.mesh, adjacency, static_cast<uint32_t>(f), to, now, block_ring)) {
          to = kNoMove;
        }
        target[f] = to;
      }
    });
    // Apply in face order. A face none of whose vertices a move of this sweep touched sees
    // its ring as the test saw it; the others are tested again against the labels now.
    applied.clear();
    for (uint32_t f = 0; f < n; ++f) {
      const uint32_t to = target[f];
      if (to == kNoMove) continue;
      const uint32_t from = partition.label(f);
      if (partition.size(from) <= 1) continue;
      const uint32_t* corners = &problem.mesh->indices[3 * size_t{f}];
      const bool touched = vertex_moved[corners[0]] == sweep || vertex_moved[corners[1]] == sweep ||
                           vertex_moved[corners[2]] == sweep;
      if (touched) {
        bool touches = false;
        for (FaceId g : adjacency.neighbours[f]) touches |= g.valid() && now[g.value()] == to;
        if (!touches) continue;
        if (guard && !RingTest(*problem.mesh, adjacency, f, to, now, ring)) continue;
      }
      applied.push_back({f, from});
      partition.Move(f, to);
      for (int c = 0; c < 3; ++c) vertex_moved[corners[c]] = sweep;
    }
    result.sweeps = sweep;
    if (applied.empty()) break;
    const double next = partition.TotalEnergy();
    if (next > current) {
      boundary_based::UndoMoves(partition, std::span<const boundary_based::AppliedMove>(applied));
      break;
    }
    current = next;
    result.moves += applied.size();
  }
  partition.RefreshAllSums();  // the energy of the labels (partition.h)
  result.energy = partition.TotalEnergy();
  const std::span<const uint32_t> final_labels = partition.labels();
  labels.assign(final_labels.begin(), final_labels.end());
  return result;
}

}  // namespace

absl::StatusOr<std::vector<FaceId>> SpreadSeeds(const MeshProblem& problem, uint32_t clusters,
                                                const std::atomic<bool>* cancel) {
  MLCLUST_RETURN_IF_ERROR(ValidateMeshProblem(problem));
  const size_t n = problem.adjacency->num_faces();
  if (clusters < 1 || clusters > n) {
    return absl::InvalidArgumentError(
        absl::StrCat("clusters: ", clusters, " must be between 1 and the mesh's ", n, " faces"));
  }
  std::vector<uint32_t> component;
  const uint32_t components = LabelFaceComponents(*problem.adjacency, component);
  if (clusters < components) {
    return absl::InvalidArgumentError(
        absl::StrCat("clusters: ", clusters, " is fewer than the mesh's ", components,
                     " connected components (a patch cannot span two components)"));
  }
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(cancel, "spread seeds"));
  // Seeds per component: one each, the other clusters - components by the faces beyond a
  // component's first (largest remainders first, ties to the smaller component id), so no
  // component gets more seeds than faces.
  std::vector<uint32_t> faces_in(components, 0);
  for (uint32_t c : component) ++faces_in[c];
  std::vector<uint32_t> seeds_in(components, 1);
  const uint64_t extra = clusters - components;
  const uint64_t spare = n - components;  // the faces beyond each component's first
  if (extra > 0) {
    std::vector<std::pair<uint64_t, uint32_t>> remainders;  // (remainder, component)
    uint64_t given = 0;
    for (uint32_t c = 0; c < components; ++c) {
      const uint64_t share = extra * (faces_in[c] - 1);
      seeds_in[c] += static_cast<uint32_t>(share / spare);
      given += share / spare;
      remainders.push_back({share % spare, c});
    }
    std::stable_sort(remainders.begin(), remainders.end(),
                     [](const auto& a, const auto& b) { return a.first > b.first; });
    for (size_t i = 0; given < extra; ++i, ++given) ++seeds_in[remainders[i].second];
  }
  const std::vector<uint32_t> codes = MortonCodes(*problem.measures);
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(cancel, "spread seeds"));
  const std::vector<uint32_t> order = FacesInMortonOrder(codes, component, components);
  std::vector<FaceId> seeds;
  seeds.reserve(clusters);
  size_t begin = 0;  // the component's first face in `order`
  for (uint32_t c = 0; c < components; ++c) {
    const uint64_t size = faces_in[c], runs = seeds_in[c];
    for (uint64_t r = 0; r < runs; ++r) {
      const uint64_t run_begin = r * size / runs, run_end = (r + 1) * size / runs;
      seeds.push_back(FaceId(order[begin + (run_begin + run_end) / 2]));
    }
    begin += size;
  }
  return seeds;
}

absl::StatusOr<PatchResult> BuildPatches(const MeshProblem& problem, const PatchOptions& options) {
  if (options.threads < 0) {
    return absl::InvalidArgumentError(absl::StrCat("threads: ", options.threads, " < 0"));
  }
  MLCLUST_ASSIGN_OR_RETURN(std::vector<FaceId> seeds,
                           SpreadSeeds(problem, options.clusters, options.cancel));
  PatchResult result;
  MLCLUST_ASSIGN_OR_RETURN(result.initial_labels,
                           GrowClustersFromSeeds(problem, seeds, options.growth, options.cancel,
                                                 &options.device_rounds));
  for (uint32_t step = 0; step < options.reseeds; ++step) {
    // Lloyd on the seeds: each cluster's seed moves to its face nearest the cluster's
    // area-weighted centroid, and all grow again.
    const FaceMeasures& measures = *problem.measures;
    std::vector<Vec3> centre(seeds.size());
    std::vector<double> area(seeds.size(), 0.0);
    for (size_t f = 0; f < result.initial_labels.size(); ++f) {
      const uint32_t c = result.initial_labels[f].value();
      const double a = measures.area[f];
      centre[c] += measures.centroid[f] * a;
      area[c] += a;
    }
    for (size_t c = 0; c < seeds.size(); ++c) {
      if (area[c] > 0) centre[c] = centre[c] * (1.0 / area[c]);
    }
    std::vector<double> best(seeds.size(), std::numeric_limits<double>::infinity());
    for (size_t f = 0; f < result.initial_labels.size(); ++f) {
      const uint32_t c = result.initial_labels[f].value();
      const Vec3 d = measures.centroid[f] - centre[c];
      const double distance = d.x * d.x + d.y * d.y + d.z * d.z;
      if (distance < best[c]) {
        best[c] = distance;
        seeds[c] = FaceId(static_cast<uint32_t>(f));
      }
    }
    MLCLUST_ASSIGN_OR_RETURN(result.initial_labels,
                             GrowClustersFromSeeds(problem, seeds, options.growth, options.cancel,
                                                   &options.device_rounds));
  }
  result.labels = result.initial_labels;
  if (options.sweeps == 0) {
    result.initial_energy = MeshEnergyOfLabels(problem.energy, *problem.mesh, result.labels);
    result.energy = result.initial_energy;
    return result;
  }
  std::vector<uint32_t> labels(result.labels.size());
  for (size_t f = 0; f < labels.size(); ++f) labels[f] = result.labels[f].value();
  MLCLUST_ASSIGN_OR_RETURN(
      const SweepResult swept,
      WithMeshEnergy(problem.energy, *problem.mesh, *problem.measures, [&](const auto& energy) {
        return Sweep(problem, energy, labels, options.clusters, options);
      }));
  for (size_t f = 0; f < labels.size(); ++f) result.labels[f] = ClusterId(labels[f]);
  result.initial_energy = swept.initial_energy;
  result.energy = swept.energy;
  result.sweeps = swept.sweeps;
  result.moves = swept.moves;
  return result;
}

}  // namespace mlclust
