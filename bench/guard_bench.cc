// Compares the two connectivity guards of core/mesh/connectivity_guard.h: our ring test
// (ConnectivityGuard, the default) and the dissertation's Alg. 3.2
// (VertexBoundaryEdgeCountGuard), under the same EMLO-style local optimisation.
//   guard_bench MESH [--clusters K] [--sweeps S] [--seed N] [--copies C] [--repeats R]
//               [--random]
// Start: K clusters grown breadth-first from random seed faces (--copies C puts C
// translated copies of the mesh side by side: C components). Then S sweeps: every
// boundary edge, in a random order, proposes moving one of its two faces to the other's
// cluster where that lowers the uniform CVD energy (eq. 3.14-3.16), as EMLO does (with
// --random: one of the two faces at random, whatever the energy, to reach configurations
// the energy seldom does). Each
// proposal asks both guards; the guard under test decides. Prints, per guard (ring, alg32,
// none): proposals, moves made, how often the two guards disagreed, nanoseconds per check
// of the guard under test (best of --repeats runs; clock reads included), the final CVD energy, and
// the clusters left disconnected, with holes or handles (Euler characteristic != 1), touching
// themselves at a vertex, or emptied.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <deque>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "absl/container/flat_hash_set.h"
#include "bench/bench_util.h"
#include "core/energy/energies.h"
#include "core/io/mesh_io.h"
#include "core/mesh/cluster_pieces.h"
#include "core/mesh/connectivity_guard.h"
#include "core/mesh/face_measures.h"
#include "core/mesh/prepared_mesh.h"

namespace {

using namespace mlclust;
using Clock = std::chrono::steady_clock;

struct Topology {
  uint32_t disconnected = 0, not_disc = 0, pinched = 0, empty = 0;
};

Topology Inspect(const TriangleMesh& mesh, const FaceAdjacency& adjacency,
                 const std::vector<uint32_t>& labels, uint32_t k) {
  Topology t;
  const size_t n = labels.size();
  std::vector<uint32_t> size(k, 0);
  for (uint32_t l : labels) ++size[l];
  for (uint32_t c = 0; c < k; ++c) t.empty += size[c] == 0;
  // Components per cluster.
  const std::vector<uint32_t> components = ClusterPieces(adjacency, labels, k);
  for (uint32_t c = 0; c < k; ++c) t.disconnected += components[c] > 1;
  // Euler characteristic V - E + F per cluster.
  std::vector<int64_t> chi(k, 0);
  absl::flat_hash_set<uint64_t> vertex_seen;
  for (uint32_t f = 0; f < n; ++f) {
    chi[labels[f]] += 1;  // F
    for (int e = 0; e < 3; ++e) {
      const FaceId h = adjacency.neighbours[f][e];
      const bool same = h.valid() && labels[h.value()] == labels[f];
      if (!same || h.value() > f) chi[labels[f]] -= 1;  // E, each edge once
      const uint32_t v = mesh.indices[3 * size_t{f} + e];
      if (vertex_seen.insert((uint64_t{labels[f]} << 32) | v).second) chi[labels[f]] += 1;
    }
  }
  for (uint32_t c = 0; c < k; ++c) t.not_disc += size[c] > 0 && components[c] == 1 && chi[c] != 1;
  // Pinches: a vertex where a cluster's faces form more than one run (faces minus the
  // cluster's interior edges at the vertex, unless they close the fan).
  const VertexFaceTable table = BuildVertexFaceTable(mesh);
  absl::flat_hash_set<uint32_t> pinched;
  for (uint32_t v = 0; v < mesh.num_vertices(); ++v) {
    std::vector<std::pair<uint32_t, int>> runs;  // cluster, faces - interior edges
    for (uint32_t f : table.faces_around(v)) {
      const uint32_t* corners = &mesh.indices[3 * size_t{f}];
      const int at = corners[0] == v ? 0 : corners[1] == v ? 1 : 2;
      int interior = 0;
      for (int e : {at, (at + 2) % 3}) {
        const FaceId h = adjacency.neighbours[f][e];
        interior += h.valid() && labels[h.value()] == labels[f];
      }
      // Each interior edge at v is seen from both faces: count halves.
      auto it = std::find_if(runs.begin(), runs.end(),
                             [&](const auto& r) { return r.first == labels[f]; });
      if (it == runs.end()) {
        runs.push_back({labels[f], 0});
        it = runs.end() - 1;
      }
      it->second += 2 - interior;  // 2 * faces - interior incidences = 2 * (F - E)
    }
    for (const auto& [cluster, twice] : runs) {
      if (twice / 2 > 1) pinched.insert(cluster);
    }
  }
  t.pinched = static_cast<uint32_t>(pinched.size());
  return t;
}

std::vector<uint32_t> Grow(const FaceAdjacency& adjacency, uint32_t k, std::mt19937& rng) {
  const uint32_t n = static_cast<uint32_t>(adjacency.num_faces());
  std::vector<uint32_t> labels(n, UINT32_MAX);
  std::deque<uint32_t> queue;
  std::vector<uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), rng);
  for (uint32_t c = 0; c < k; ++c) {
    labels[order[c]] = c;
    queue.push_back(order[c]);
  }
  uint32_t next_seed = k, clusters = k;
  for (;;) {
    while (!queue.empty()) {
      const uint32_t f = queue.front();
      queue.pop_front();
      for (FaceId h : adjacency.neighbours[f]) {
        if (h.valid() && labels[h.value()] == UINT32_MAX) {
          labels[h.value()] = labels[f];
          queue.push_back(h.value());
        }
      }
    }
    // Components no seed reached get a cluster of their own.
    while (next_seed < n && labels[order[next_seed]] != UINT32_MAX) ++next_seed;
    if (next_seed == n) break;
    labels[order[next_seed]] = clusters++;
    queue.push_back(order[next_seed]);
  }
  return labels;
}

struct Result {
  uint64_t proposals = 0, moves = 0, ring_only = 0, alg_only = 0;
  double ring_ns = 0, alg_ns = 0, energy = 0;
  Topology before, after;
};

enum class Mode { kRing, kAlg32, kNone };

Result Run(const TriangleMesh& mesh, const FaceAdjacency& adjacency, const FaceMeasures& measures,
           std::vector<uint32_t> labels, uint32_t k, int sweeps, uint32_t seed, Mode mode,
           bool random_moves) {
  Result r;
  r.before = Inspect(mesh, adjacency, labels, k);
  const CvdEnergy energy(measures);
  std::vector<CvdSums> sums(k);
  std::vector<uint32_t> sizes(k, 0);
  for (size_t f = 0; f < labels.size(); ++f) {
    sums[labels[f]] += energy.face_sums(f);
    ++sizes[labels[f]];
  }
  const ConnectivityGuard ring(mesh, adjacency);
  VertexBoundaryEdgeCountGuard alg(mesh, adjacency);
  alg.Reset(labels);
  std::mt19937 rng(seed);
  std::vector<std::pair<uint32_t, int>> edges;
  double ring_seconds = 0, alg_seconds = 0;
  uint64_t checks = 0;
  for (int sweep = 0; sweep < sweeps; ++sweep) {
    edges.clear();
    for (uint32_t f = 0; f < labels.size(); ++f) {
      for (int e = 0; e < 3; ++e) {
        const FaceId h = adjacency.neighbours[f][e];
        if (h.valid() && h.value() > f && labels[h.value()] != labels[f]) edges.push_back({f, e});
      }
    }
    std::shuffle(edges.begin(), edges.end(), rng);
    for (const auto& [f, e] : edges) {
      const uint32_t g = adjacency.neighbours[f][e].value();
      const uint32_t a = labels[f], b = labels[g];
      if (a == b) continue;
      // Eq. 3.14-3.16: the current configuration, f to b, or g to a.
      const double e0 = CvdSumsEnergy(sums[a]) + CvdSumsEnergy(sums[b]);
      CvdSums a1 = sums[a], b1 = sums[b], a2 = sums[a], b2 = sums[b];
      a1 -= energy.face_sums(f);
      b1 += energy.face_sums(f);
      a2 += energy.face_sums(g);
      b2 -= energy.face_sums(g);
      const double e1 = CvdSumsEnergy(a1) + CvdSumsEnergy(b1);
      const double e2 = CvdSumsEnergy(a2) + CvdSumsEnergy(b2);
      uint32_t face, to;
      if (random_moves) {
        const bool first = rng() & 1;
        face = first ? f : g;
        to = first ? b : a;
      } else if (e1 < e2 && e1 < e0 * (1 - 1e-12)) {
        face = f, to = b;
      } else if (e2 < e0 * (1 - 1e-12)) {
        face = g, to = a;
      } else {
        continue;
      }
      ++r.proposals;
      // The active guard's check alone is timed (in batches of one, with the clock's own
      // cost included alike for both); the other is asked afterwards for the comparison.
      const auto t0 = Clock::now();
      const bool active_ok = mode == Mode::kRing    ? ring.CanMove(face, to, labels, sizes)
                             : mode == Mode::kAlg32 ? alg.CanMove(face, to, labels, sizes)
                                                    : sizes[labels[face]] > 1;
      const auto t1 = Clock::now();
      (mode == Mode::kAlg32 ? alg_seconds : ring_seconds) +=
          std::chrono::duration<double>(t1 - t0).count();
      ++checks;
      const bool ring_ok = mode == Mode::kRing ? active_ok : ring.CanMove(face, to, labels, sizes);
      const bool alg_ok = mode == Mode::kAlg32 ? active_ok : alg.CanMove(face, to, labels, sizes);
      r.ring_only += ring_ok && !alg_ok;
      r.alg_only += alg_ok && !ring_ok;
      const bool allowed = active_ok;
      if (!allowed) continue;
      const uint32_t from = labels[face];
      sums[from] -= energy.face_sums(face);
      sums[to] += energy.face_sums(face);
      --sizes[from];
      ++sizes[to];
      labels[face] = to;
      alg.OnMove(face, from, labels);
      ++r.moves;
    }
  }
  r.ring_ns = checks && mode == Mode::kRing ? ring_seconds / checks * 1e9 : 0;
  r.alg_ns = checks && mode == Mode::kAlg32 ? alg_seconds / checks * 1e9 : 0;
  for (const CvdSums& s : sums) r.energy += CvdSumsEnergy(s);
  r.after = Inspect(mesh, adjacency, labels, k);
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  bench::Args args(argc, argv,
                   "usage: guard_bench MESH [--clusters K] [--sweeps S] [--seed N] [--copies C] "
                   "[--repeats R] [--random] [--header]");
  const bool header = args.Flag("header");
  const bool random_moves = args.Flag("random");
  const std::string path = args.Positional(0);
  const uint32_t k = args.Get<uint32_t>("clusters", 200);
  const int sweeps = args.Get<int>("sweeps", 20);
  const uint32_t seed = args.Get<uint32_t>("seed", 1);
  const uint32_t repeats = args.Get<uint32_t>("repeats", 3);
  const uint32_t copies = args.Get<uint32_t>("copies", 1);
  if (!args.Done()) return 2;
  absl::StatusOr<TriangleMesh> loaded = ReadMeshFile(path);
  if (!loaded.ok()) {
    std::fprintf(stderr, "%s\n", loaded.status().ToString().c_str());
    return 1;
  }
  TriangleMesh mesh;
  float width = 0;
  for (size_t v = 0; v < loaded->num_vertices(); ++v) {
    width = std::max(width, std::abs(loaded->positions[3 * v]) * 2);
  }
  for (uint32_t copy = 0; copy < copies; ++copy) {
    const uint32_t offset = static_cast<uint32_t>(mesh.num_vertices());
    for (size_t v = 0; v < loaded->num_vertices(); ++v) {
      mesh.positions.push_back(loaded->positions[3 * v] + copy * 1.5f * width);
      mesh.positions.push_back(loaded->positions[3 * v + 1]);
      mesh.positions.push_back(loaded->positions[3 * v + 2]);
    }
    for (uint32_t i : loaded->indices) mesh.indices.push_back(i + offset);
  }
  // The copies together, validated, with adjacency and measures.
  absl::StatusOr<PreparedMesh> prepared = PrepareMesh(std::move(mesh));
  if (!prepared.ok()) {
    std::fprintf(stderr, "%s\n", prepared.status().ToString().c_str());
    return 1;
  }
  mesh = std::move(prepared->mesh);
  const FaceAdjacency* adjacency = &prepared->adjacency;
  const FaceMeasures& measures = prepared->measures;
  std::mt19937 rng(seed);
  const std::vector<uint32_t> labels = Grow(*adjacency, k, rng);
  const uint32_t clusters = *std::max_element(labels.begin(), labels.end()) + 1;
  if (header) {
    std::printf(
        "mesh,faces,copies,clusters,sweeps,seed,moves_from,guard,proposals,moves,ring_only,"
        "alg32_only,ring_ns,alg32_ns,energy,disconnected_before,not_disc_before,pinched_before,"
        "disconnected,not_disc,pinched,emptied\n");
  }
  const std::string base_name = bench::BaseName(path);
  const char* name = base_name.c_str();
  for (Mode mode : {Mode::kRing, Mode::kAlg32, Mode::kNone}) {
    Result r = Run(mesh, *adjacency, measures, labels, clusters, sweeps, seed, mode, random_moves);
    for (uint32_t repeat = 1; repeat < repeats; ++repeat) {
      const Result again =
          Run(mesh, *adjacency, measures, labels, clusters, sweeps, seed, mode, random_moves);
      r.ring_ns = std::min(r.ring_ns, again.ring_ns);
      r.alg_ns = std::min(r.alg_ns, again.alg_ns);
    }
    std::printf(
        "%s,%zu,%u,%u,%d,%u,%s,%s,%llu,%llu,%llu,%llu,%.1f,%.1f,%.6g,%u,%u,%u,%u,%u,%u,%u\n", name,
        mesh.num_faces(), copies, clusters, sweeps, seed, random_moves ? "random" : "cvd",
        mode == Mode::kRing    ? "ring"
        : mode == Mode::kAlg32 ? "alg32"
                               : "none",
        static_cast<unsigned long long>(r.proposals), static_cast<unsigned long long>(r.moves),
        static_cast<unsigned long long>(r.ring_only), static_cast<unsigned long long>(r.alg_only),
        r.ring_ns, r.alg_ns, r.energy, r.before.disconnected, r.before.not_disc, r.before.pinched,
        r.after.disconnected, r.after.not_disc, r.after.pinched, r.after.empty);
  }
  return 0;
}
