#include "core/mesh/connectivity_guard.h"

#include <algorithm>

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
  const size_t n = adjacency.num_faces();
  ring_offset_.assign(n + 1, 0);
  ring_faces_.reserve(13 * n);
  std::vector<uint32_t> ring;
  for (uint32_t face = 0; face < n; ++face) {
    ring.clear();
    // Corner walks go n_i .. n_{i+2}; chaining corners 0, 2, 1 closes the cycle
    // n_0 .. n_2 .. n_1 .. n_0. Each walk's last face starts the next walk, and gaps of
    // neighbouring walks meet: collapse equal neighbours, cyclically.
    for (int corner : {0, 2, 1}) CornerWalk(mesh, adjacency, face, corner, ring);
    ring.erase(std::unique(ring.begin(), ring.end()), ring.end());
    while (ring.size() > 1 && ring.front() == ring.back()) ring.pop_back();
    ring_faces_.insert(ring_faces_.end(), ring.begin(), ring.end());
    ring_offset_[face + 1] = ring_faces_.size();
  }
}

bool ConnectivityGuard::CanMove(uint32_t face, uint32_t to, std::span<const uint32_t> labels,
                                std::span<const uint32_t> cluster_sizes) const {
  const uint32_t from = labels[face];
  if (from == to || cluster_sizes[from] <= 1) return false;
  // Count the runs of `from` and of `to` around the ring in one pass: a run starts where
  // a face of the cluster follows one that is not (a gap is in no cluster).
  const std::span<const uint32_t> ring = Ring(face);
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

}  // namespace mlclust
