// The connectivity guard of EMLO (Alg. 3.2's purpose): a face may change cluster only if
// the move neither splits the cluster it leaves nor closes a loop in the cluster it joins.
// So a clustering whose clusters are edge-connected discs stays so under any sequence of
// allowed moves: no cluster splits, none gains a hole or a handle.
//
// The test is local. The faces that share a vertex with face f form a ring around it
// (a cycle for an interior face; broken where the mesh has a boundary). Moving f from A
// to B is allowed iff A keeps another face, the faces of A in the ring form exactly one
// run and the faces of B in the ring form exactly one run (consecutive ring faces share
// an edge, so a run is edge-connected; a mesh boundary breaks runs). This is the
// simple-point test of digital topology applied to faces. The dissertation's Alg. 3.2
// tracks per-vertex counts of boundary edges (cases 0-4) to reach the same decision; its
// text was not available to us, so this is our formulation of the same guarantee.
#ifndef MLCLUST_CORE_MESH_CONNECTIVITY_GUARD_H_
#define MLCLUST_CORE_MESH_CONNECTIVITY_GUARD_H_

#include <cstdint>
#include <span>
#include <vector>

#include "core/mesh/mesh.h"

namespace mlclust {

class ConnectivityGuard {
 public:
  // Builds every face's ring once (about 13 ids per face), so that a check is a scan of
  // a dozen labels. Needs a mesh that passed ValidateMesh and its adjacency.
  ConnectivityGuard(const TriangleMesh& mesh, const FaceAdjacency& adjacency);

  // Whether face `face` may move from its cluster labels[face] to cluster `to`, given the
  // cluster sizes (faces per cluster id). labels holds one cluster id per face.
  bool CanMove(uint32_t face, uint32_t to, std::span<const uint32_t> labels,
               std::span<const uint32_t> cluster_sizes) const;

  // The faces around `face` in ring order (cyclic), kGap where the mesh boundary breaks
  // the ring.
  static constexpr uint32_t kGap = 0xffffffffu;
  std::span<const uint32_t> Ring(uint32_t face) const {
    return {ring_faces_.data() + ring_offset_[face], ring_offset_[face + 1] - ring_offset_[face]};
  }

 private:
  std::vector<uint64_t> ring_offset_;
  std::vector<uint32_t> ring_faces_;
};

}  // namespace mlclust

#endif  // MLCLUST_CORE_MESH_CONNECTIVITY_GUARD_H_
