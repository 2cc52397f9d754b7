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
#ifndef MLCLUST_CORE_CONNECTIVITY_GUARD_H_
#define MLCLUST_CORE_CONNECTIVITY_GUARD_H_

#include <cstdint>
#include <span>
#include <vector>

#include "core/mesh.h"

namespace mlclust {

class ConnectivityGuard {
 public:
  // Both must outlive the guard. Needs a mesh that passed ValidateMesh.
  ConnectivityGuard(const TriangleMesh& mesh, const FaceAdjacency& adjacency)
      : mesh_(mesh), adjacency_(adjacency) {}

  // Whether face `face` may move from its cluster labels[face] to cluster `to`, given the
  // cluster sizes (faces per cluster id). labels holds one cluster id per face.
  bool CanMove(uint32_t face, uint32_t to, std::span<const uint32_t> labels,
               std::span<const uint32_t> cluster_sizes) const;

  // The faces around `face` in ring order, kGap where the mesh boundary breaks the ring.
  // Exposed for tests. `ring` is cleared first.
  static constexpr uint32_t kGap = 0xffffffffu;
  void Ring(uint32_t face, std::vector<uint32_t>& ring) const;

 private:
  // Faces around corner vertex `corner` of `face`, from the neighbour across edge `corner`
  // to the neighbour across edge (corner + 2) % 3, both included, kGap at a boundary.
  void CornerWalk(uint32_t face, int corner, std::vector<uint32_t>& out) const;

  const TriangleMesh& mesh_;
  const FaceAdjacency& adjacency_;
};

}  // namespace mlclust

#endif  // MLCLUST_CORE_CONNECTIVITY_GUARD_H_
