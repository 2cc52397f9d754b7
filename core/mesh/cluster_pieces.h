// The edge-connected pieces of each cluster of a face labelling: what the tests and benches
// check of a clustering that must keep its clusters connected (the connectivity guard's
// contract, core/mesh/connectivity_guard.h).
#ifndef MLCLUST_CORE_MESH_CLUSTER_PIECES_H_
#define MLCLUST_CORE_MESH_CLUSTER_PIECES_H_

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "core/mesh/mesh.h"

namespace mlclust {

// pieces[c]: how many edge-connected pieces the faces labelled c form (0 for no face), for
// labels[f] < k, labels.size() == adjacency.num_faces(). O(faces), a depth-first search.
inline std::vector<uint32_t> ClusterPieces(const FaceAdjacency& adjacency,
                                           std::span<const uint32_t> labels, uint32_t k) {
  std::vector<uint32_t> pieces(k, 0);
  std::vector<uint8_t> seen(labels.size(), 0);
  std::vector<uint32_t> stack;
  for (uint32_t f = 0; f < labels.size(); ++f) {
    if (seen[f]) continue;
    ++pieces[labels[f]];
    seen[f] = 1;
    stack.assign(1, f);
    while (!stack.empty()) {
      const uint32_t g = stack.back();
      stack.pop_back();
      for (const FaceId h : adjacency.neighbours[g]) {
        if (h.valid() && !seen[h.value()] && labels[h.value()] == labels[g]) {
          seen[h.value()] = 1;
          stack.push_back(h.value());
        }
      }
    }
  }
  return pieces;
}

// The clusters of `labels` (ids below labels.size(), as a hierarchy's) in more than one
// piece.
inline size_t DisconnectedClusters(const FaceAdjacency& adjacency,
                                   std::span<const uint32_t> labels) {
  size_t disconnected = 0;
  for (const uint32_t p : ClusterPieces(adjacency, labels, static_cast<uint32_t>(labels.size()))) {
    disconnected += p > 1 ? 1 : 0;
  }
  return disconnected;
}

}  // namespace mlclust

#endif  // MLCLUST_CORE_MESH_CLUSTER_PIECES_H_
