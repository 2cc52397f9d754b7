#include "core/mesh/connectivity_guard.h"

#include <algorithm>
#include <array>
#include <utility>

#include "core/base/cancel.h"

namespace mlclust {
namespace {

int CornerOf(const TriangleMesh& mesh, uint32_t face, uint32_t vertex) {
  const uint32_t* f = &mesh.indices[3 * size_t{face}];
  return f[0] == vertex ? 0 : f[1] == vertex ? 1 : 2;
}

// Faces around corner vertex `corner` of `face`, from the neighbour across edge `corner`
// to the neighbour across edge (corner + 2) % 3, both included, kGap at a boundary.
void CornerWalk(const TriangleMesh& mesh, const FaceAdjacency& adjacency, uint32_t face, int corner,
                std::vector<uint32_t>& out) {
  constexpr uint32_t kGap = ConnectivityGuard::kGap;
  const uint32_t vertex = mesh.indices[3 * size_t{face} + corner];
  const FaceId first = adjacency.neighbours[face][corner];
  const FaceId last = adjacency.neighbours[face][(corner + 2) % 3];
  // Steps from `current` (entered from `previous`) to the next face around `vertex`:
  // across the other edge of `current` that contains the vertex. Orientation-free.
  auto step = [&](uint32_t previous, uint32_t current) -> uint32_t {
    const int c = CornerOf(mesh, current, vertex);
    const FaceId a = adjacency.neighbours[current][c];
    const FaceId b = adjacency.neighbours[current][(c + 2) % 3];
    const FaceId next = (a.valid() && a.value() == previous) ? b : a;
    return next.valid() ? next.value() : kGap;
  };
  // Forward from the neighbour across `corner` until we come back to `face`.
  uint32_t previous = face;
  uint32_t current = first.valid() ? first.value() : kGap;
  size_t guard = 0;
  while (current != kGap && current != face && guard++ < 4096) {
    out.push_back(current);
    const uint32_t next = step(previous, current);
    previous = current;
    current = next;
  }
  if (current == face) return;  // closed fan: ends with `last`
  // A boundary: walk from `last` the other way and append that part reversed.
  out.push_back(kGap);
  const size_t backward_start = out.size();
  previous = face;
  current = last.valid() ? last.value() : kGap;
  guard = 0;
  while (current != kGap && current != face && guard++ < 4096) {
    out.push_back(current);
    const uint32_t next = step(previous, current);
    previous = current;
    current = next;
  }
  std::reverse(out.begin() + backward_start, out.end());
}

}  // namespace

ConnectivityGuard::ConnectivityGuard(const TriangleMesh& mesh, const FaceAdjacency& adjacency) {
  BuildRings(mesh, adjacency, nullptr);
}

absl::StatusOr<ConnectivityGuard> ConnectivityGuard::Build(const TriangleMesh& mesh,
                                                           const FaceAdjacency& adjacency,
                                                           const std::atomic<bool>* cancel) {
  ConnectivityGuard guard;
  if (!guard.BuildRings(mesh, adjacency, cancel)) {
    return absl::CancelledError("cancelled while building the connectivity guard");
  }
  return guard;
}

ConnectivityGuard ConnectivityGuard::FromRings(std::vector<uint64_t> offset,
                                               std::vector<uint32_t> ring_elements) {
  ConnectivityGuard guard;
  guard.ring_offset_ = std::move(offset);
  guard.ring_faces_ = std::move(ring_elements);
  return guard;
}

bool ConnectivityGuard::BuildRings(const TriangleMesh& mesh, const FaceAdjacency& adjacency,
                                   const std::atomic<bool>* cancel) {
  const size_t n = adjacency.num_faces();
  ring_offset_.assign(n + 1, 0);
  ring_faces_.reserve(13 * n);
  std::vector<uint32_t> ring;
  for (uint32_t face = 0; face < n; ++face) {
    if (face % 16384 == 0 && IsCancelled(cancel)) return false;
    BuildFaceRing(mesh, adjacency, face, ring);
    ring_faces_.insert(ring_faces_.end(), ring.begin(), ring.end());
    ring_offset_[face + 1] = ring_faces_.size();
  }
  return true;
}

bool ConnectivityGuard::CanMove(uint32_t face, uint32_t to, std::span<const uint32_t> labels,
                                std::span<const uint32_t> cluster_sizes) const {
  const uint32_t from = labels[face];
  if (from == to || cluster_sizes[from] <= 1) return false;
  return RingTestAllows(Ring(face), from, to, labels);
}

void BuildFaceRing(const TriangleMesh& mesh, const FaceAdjacency& adjacency, uint32_t face,
                   std::vector<uint32_t>& ring) {
  ring.clear();
  // Corner walks go n_i .. n_{i+2}; chaining corners 0, 2, 1 closes the cycle
  // n_0 .. n_2 .. n_1 .. n_0. Each walk's last face starts the next walk, and gaps of
  // neighbouring walks meet: collapse equal neighbours, cyclically.
  for (int corner : {0, 2, 1}) CornerWalk(mesh, adjacency, face, corner, ring);
  ring.erase(std::unique(ring.begin(), ring.end()), ring.end());
  while (ring.size() > 1 && ring.front() == ring.back()) ring.pop_back();
}

bool RingTestAllows(std::span<const uint32_t> ring, uint32_t from, uint32_t to,
                    std::span<const uint32_t> labels) {
  constexpr uint32_t kGap = ConnectivityGuard::kGap;
  // Count the runs of `from` and of `to` around the ring in one pass: a run starts where
  // a face of the cluster follows one that is not (a gap is in no cluster).
  const size_t n = ring.size();
  if (n == 0) return false;
  auto label_at = [&](size_t i) {
    const uint32_t g = ring[i];
    return g == kGap ? kGap : labels[g];
  };
  uint32_t previous = label_at(n - 1);
  int from_runs = 0, to_runs = 0;
  bool any_from = false, any_to = false;
  for (size_t i = 0; i < n; ++i) {
    const uint32_t current = label_at(i);
    if (current == from) {
      any_from = true;
      from_runs += previous != from;
    } else if (current == to) {
      any_to = true;
      to_runs += previous != to;
    }
    previous = current;
  }
  if (any_from && from_runs == 0) from_runs = 1;  // the whole ring is one cluster
  if (any_to && to_runs == 0) to_runs = 1;
  return from_runs == 1 && to_runs == 1;
}

// ---------------------------------------------------------------------------------------
// Alg. 3.2.

VertexBoundaryEdgeCountGuard::VertexBoundaryEdgeCountGuard(const TriangleMesh& mesh,
                                                           const FaceAdjacency& adjacency)
    : mesh_(mesh),
      adjacency_(adjacency),
      vertex_faces_(BuildVertexFaceTable(mesh)),
      count_(mesh.num_vertices(), 0) {}

void VertexBoundaryEdgeCountGuard::Reset(std::span<const uint32_t> labels) {
  std::fill(count_.begin(), count_.end(), 0);
  for (uint32_t face = 0; face < adjacency_.num_faces(); ++face) {
    for (int e = 0; e < 3; ++e) {
      const FaceId across = adjacency_.neighbours[face][e];
      // Each interior edge once (from its lower face); border edges from their only face.
      if (across.valid() && (across.value() < face || labels[across.value()] == labels[face])) {
        continue;
      }
      ++count_[mesh_.indices[3 * size_t{face} + e]];
      ++count_[mesh_.indices[3 * size_t{face} + (e + 1) % 3]];
    }
  }
}

bool VertexBoundaryEdgeCountGuard::CanMove(uint32_t face, uint32_t to,
                                           std::span<const uint32_t> labels,
                                           std::span<const uint32_t> cluster_sizes) const {
  return Check(face, to, labels, cluster_sizes, [&](uint32_t v2) { return count_[v2] == 0; });
}

bool VertexBoundaryEdgeCountGuard::CanMoveWithoutCounts(
    uint32_t face, uint32_t to, std::span<const uint32_t> labels,
    std::span<const uint32_t> cluster_sizes) const {
  // count(V2) == 0: every face around V2 in the moving face's cluster and no mesh border
  // edge at V2 (then every edge at V2 has the same cluster on both sides).
  return Check(face, to, labels, cluster_sizes, [&](uint32_t v2) {
    const uint32_t from = labels[face];
    for (uint32_t g : vertex_faces_.faces_around(v2)) {
      if (labels[g] != from) return false;
      const uint32_t* corners = &mesh_.indices[3 * size_t{g}];
      const int at = corners[0] == v2 ? 0 : corners[1] == v2 ? 1 : 2;
      for (int e : {at, (at + 2) % 3}) {
        if (!adjacency_.neighbours[g][e].valid()) return false;
      }
    }
    return true;
  });
}

template <typename CaseZero>
bool VertexBoundaryEdgeCountGuard::Check(uint32_t face, uint32_t to,
                                         std::span<const uint32_t> labels,
                                         std::span<const uint32_t> cluster_sizes,
                                         CaseZero&& v2_has_no_boundary_edge) const {
  const uint32_t from = labels[face];
  if (from == to || cluster_sizes[from] <= 1) return false;
  const std::array<FaceId, 3>& across = adjacency_.neighbours[face];
  auto in = [&](FaceId f, uint32_t cluster) { return f.valid() && labels[f.value()] == cluster; };
  // c: the first edge whose neighbour is in `to`; edge i runs from corner i to i + 1.
  int c = 0;
  while (c < 3 && !in(across[c], to)) ++c;
  if (c == 3) return false;
  const FaceId n = across[(c + 1) % 3];  // V3 -> V2
  const FaceId p = across[(c + 2) % 3];  // V2 -> V1
  const uint32_t v2 = mesh_.indices[3 * size_t{face} + (c + 2) % 3];
  if (v2_has_no_boundary_edge(v2)) return true;  // case 0
  if (in(n, to) != in(p, to)) return true;       // cases 1, 2
  if (in(n, from) == in(p, from)) return false;  // isBoundary(n) XOR isBoundary(p) fails
  // Cases 3, 4: V2 must have no boundary edge of `to` (else `to` would close a loop around
  // a non-`to` region, Fig. 3.9 (c)). An edge of a `to` face at V2 is a boundary of `to`
  // when the face across it is not in `to` (or there is none).
  for (uint32_t g : vertex_faces_.faces_around(v2)) {
    if (labels[g] != to) continue;
    const uint32_t* corners = &mesh_.indices[3 * size_t{g}];
    const int at = corners[0] == v2 ? 0 : corners[1] == v2 ? 1 : 2;
    for (int e : {at, (at + 2) % 3}) {  // the two edges of g that contain V2
      if (!in(adjacency_.neighbours[g][e], to)) return false;
    }
  }
  return true;
}

void VertexBoundaryEdgeCountGuard::OnMove(uint32_t face, uint32_t from,
                                          std::span<const uint32_t> labels_after) {
  const uint32_t to = labels_after[face];
  for (int e = 0; e < 3; ++e) {
    const FaceId across = adjacency_.neighbours[face][e];
    if (!across.valid()) continue;  // a border edge stays a boundary edge
    const uint32_t other = labels_after[across.value()];
    const int before = other != from;
    const int after = other != to;
    if (before == after) continue;
    const uint32_t a = mesh_.indices[3 * size_t{face} + e];
    const uint32_t b = mesh_.indices[3 * size_t{face} + (e + 1) % 3];
    count_[a] += after - before;
    count_[b] += after - before;
  }
}

}  // namespace mlclust
