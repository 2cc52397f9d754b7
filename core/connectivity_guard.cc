#include "core/connectivity_guard.h"

#include <algorithm>

namespace mlclust {
namespace {

int CornerOf(const TriangleMesh& mesh, uint32_t face, uint32_t vertex) {
  const uint32_t* f = &mesh.indices[3 * size_t{face}];
  return f[0] == vertex ? 0 : f[1] == vertex ? 1 : 2;
}

// Number of maximal runs of faces labelled `cluster` in the cyclic sequence `ring`.
int CountRuns(const std::vector<uint32_t>& ring, std::span<const uint32_t> labels,
              uint32_t cluster) {
  const size_t n = ring.size();
  auto in = [&](size_t i) {
    const uint32_t face = ring[i % n];
    return face != ConnectivityGuard::kGap && labels[face] == cluster;
  };
  int runs = 0;
  bool any = false;
  for (size_t i = 0; i < n; ++i) {
    if (!in(i)) continue;
    any = true;
    if (!in(i + n - 1)) ++runs;
  }
  return runs == 0 && any ? 1 : runs;  // the whole ring is one cluster
}

}  // namespace

void ConnectivityGuard::CornerWalk(uint32_t face, int corner, std::vector<uint32_t>& out) const {
  const uint32_t vertex = mesh_.indices[3 * size_t{face} + corner];
  const FaceId first = adjacency_.neighbours[face][corner];
  const FaceId last = adjacency_.neighbours[face][(corner + 2) % 3];
  // Steps from `current` (entered from `previous`) to the next face around `vertex`:
  // across the other edge of `current` that contains the vertex. Orientation-free.
  auto step = [&](uint32_t previous, uint32_t current) -> uint32_t {
    const int c = CornerOf(mesh_, current, vertex);
    const FaceId a = adjacency_.neighbours[current][c];
    const FaceId b = adjacency_.neighbours[current][(c + 2) % 3];
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

void ConnectivityGuard::Ring(uint32_t face, std::vector<uint32_t>& ring) const {
  ring.clear();
  // Corner walks go n_i .. n_{i+2}; chaining corners 0, 2, 1 closes the cycle
  // n_0 .. n_2 .. n_1 .. n_0. Each walk's last face starts the next walk, and gaps of
  // neighbouring walks meet: collapse equal neighbours, cyclically.
  for (int corner : {0, 2, 1}) CornerWalk(face, corner, ring);
  ring.erase(std::unique(ring.begin(), ring.end()), ring.end());
  while (ring.size() > 1 && ring.front() == ring.back()) ring.pop_back();
}

bool ConnectivityGuard::CanMove(uint32_t face, uint32_t to, std::span<const uint32_t> labels,
                                std::span<const uint32_t> cluster_sizes) const {
  const uint32_t from = labels[face];
  if (from == to || cluster_sizes[from] <= 1) return false;
  thread_local std::vector<uint32_t> ring;
  Ring(face, ring);
  return CountRuns(ring, labels, from) == 1 && CountRuns(ring, labels, to) == 1;
}

}  // namespace mlclust
