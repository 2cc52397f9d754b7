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
// simple-point test of digital topology applied to faces: ours, and the default.
//
// VertexBoundaryEdgeCountGuard below is the dissertation's Alg. 3.2 (l. 870-890), kept
// beside it: per-vertex counts of cluster boundary edges with O(1) updates, and the test
// of cases 0-4 at the vertex opposite the boundary edge the move crosses. BENCHMARKS.md
// ("Connectivity guards") compares the moves each allows and what they leave behind.
#ifndef MLCLUST_CORE_MESH_CONNECTIVITY_GUARD_H_
#define MLCLUST_CORE_MESH_CONNECTIVITY_GUARD_H_

#include <atomic>
#include <cstdint>
#include <span>
#include <vector>

#include "absl/status/statusor.h"
#include "core/mesh/mesh.h"

namespace mlclust {

// Which connectivity check a driver asks before a face changes cluster.
enum class ConnectivityGuardKind {
  kRingTest,                 // ConnectivityGuard: ours, the default (keeps discs discs)
  kVertexBoundaryEdgeCount,  // VertexBoundaryEdgeCountGuard: Alg. 3.2 (l. 870-890)
  kOff,                      // none: only "a cluster keeps one face"
};

class ConnectivityGuard {
 public:
  // Builds every face's ring once (about 13 ids per face), so that a check is a scan of
  // a dozen labels. Needs a mesh that passed ValidateMesh and its adjacency.
  ConnectivityGuard(const TriangleMesh& mesh, const FaceAdjacency& adjacency);

  // The same, CANCELLED if `cancel` (core/base/cancel.h) is set while the rings are built
  // (checked every few thousand faces; about 0.3 s for a million faces).
  static absl::StatusOr<ConnectivityGuard> Build(const TriangleMesh& mesh,
                                                 const FaceAdjacency& adjacency,
                                                 const std::atomic<bool>* cancel);

  // The same test over any elements from their rings given in compressed rows (element
  // i's ring is ring_elements[offset[i] .. offset[i + 1]), element ids or kGap, cyclic):
  // core/mesh/polygons.h builds the polygons' guard this way.
  static ConnectivityGuard FromRings(std::vector<uint64_t> offset,
                                     std::vector<uint32_t> ring_elements);

  // Whether face `face` may move from its cluster labels[face] to cluster `to`, given the
  // cluster sizes (faces per cluster id). labels holds one cluster id per face.
  bool CanMove(uint32_t face, uint32_t to, std::span<const uint32_t> labels,
               std::span<const uint32_t> cluster_sizes) const;

  // The faces around `face` in ring order (cyclic), kGap where the mesh boundary breaks
  // the ring.
  static constexpr uint32_t kGap = FaceId::kInvalidValue;  // "no face here"
  std::span<const uint32_t> Ring(uint32_t face) const {
    return {ring_faces_.data() + ring_offset_[face], ring_offset_[face + 1] - ring_offset_[face]};
  }

 private:
  ConnectivityGuard() = default;
  // False if cancelled.
  bool BuildRings(const TriangleMesh& mesh, const FaceAdjacency& adjacency,
                  const std::atomic<bool>* cancel);

  std::vector<uint64_t> ring_offset_;
  std::vector<uint32_t> ring_faces_;
};

// The ring of `face` as ConnectivityGuard stores it (faces around it in cyclic order, kGap
// where the mesh boundary breaks it), built on demand into `ring`: for a driver that
// checks few faces and cannot afford every face's ring up front (core/cluster/patches.h).
void BuildFaceRing(const TriangleMesh& mesh, const FaceAdjacency& adjacency, uint32_t face,
                   std::vector<uint32_t>& ring);

// ConnectivityGuard::CanMove's test on a given ring: the faces of `from` and those of `to`
// each form exactly one run (the caller checks that `from` keeps another face).
bool RingTestAllows(std::span<const uint32_t> ring, uint32_t from, uint32_t to,
                    std::span<const uint32_t> labels);

// Alg. 3.2, the Vertex Boundary-Edge Count check (l. 870-890). A face F = (V1, V2, V3) of
// cluster A may join the cluster `curr` across a boundary edge c = V1 -> V3 (F's edge whose
// neighbour is in curr; the first such in F's edge order), with n = V3 -> V2 the next and
// p = V2 -> V1 the previous edge of F, iff
//   count(V2) == 0                                                        (case 0)
//   or isBoundaryOfCurr(n) XOR isBoundaryOfCurr(p)                        (cases 1, 2)
//   or (isBoundary(n) XOR isBoundary(p)) and V2 has no boundary edge of curr (cases 3, 4)
// and A keeps another face (the text's "implicit deletion of one cluster"). count(V) is the
// number of cluster boundary edges at V: edges whose two faces differ in cluster, and, our
// reading for open meshes, mesh border edges (so a vertex on a hole never passes case 0).
// isBoundaryOfCurr(e): the face across e is in curr; isBoundary(e): the face across e is
// not in A or there is none.
//
// Stateful: Reset(labels) computes the counts, OnMove keeps them in O(1) per move (each of
// the moved face's three edges changes its boundary status at most once; this reduces to
// the text's case updates, e.g. case 0: count(V2) = 2, V1 and V3 unchanged).
class VertexBoundaryEdgeCountGuard {
 public:
  // Needs a mesh that passed ValidateMesh and its adjacency; both must outlive the guard.
  VertexBoundaryEdgeCountGuard(const TriangleMesh& mesh, const FaceAdjacency& adjacency);

  // Counts the boundary edges of the clustering `labels` (one cluster id per face).
  void Reset(std::span<const uint32_t> labels);

  // Alg. 3.2 for moving `face` from labels[face] to `to`; `labels` must be those the
  // counts were last brought up to date with. False when `to` is the face's own cluster, no
  // edge of the face borders `to`, or the face is its cluster's last.
  bool CanMove(uint32_t face, uint32_t to, std::span<const uint32_t> labels,
               std::span<const uint32_t> cluster_sizes) const;

  // The same check with count(V2) == 0 read off V2's faces (no boundary edge at V2)
  // instead of the kept counts: O(valence), needs no Reset or OnMove, so a driver that
  // relabels many faces at once (ML's merges) can use Alg. 3.2 without keeping counts.
  // Gives CanMove's answer whenever the counts are up to date with `labels`.
  bool CanMoveWithoutCounts(uint32_t face, uint32_t to, std::span<const uint32_t> labels,
                            std::span<const uint32_t> cluster_sizes) const;

  // After `face` moved from `from` to labels_after[face]: the counts of its three edges'
  // ends, updated in O(1).
  void OnMove(uint32_t face, uint32_t from, std::span<const uint32_t> labels_after);

  uint32_t count(uint32_t vertex) const { return count_[vertex]; }

 private:
  // Alg. 3.2; `v2_has_no_boundary_edge(v2)` answers case 0.
  template <typename CaseZero>
  bool Check(uint32_t face, uint32_t to, std::span<const uint32_t> labels,
             std::span<const uint32_t> cluster_sizes, CaseZero&& v2_has_no_boundary_edge) const;

  const TriangleMesh& mesh_;
  const FaceAdjacency& adjacency_;
  VertexFaceTable vertex_faces_;
  std::vector<uint32_t> count_;
};

}  // namespace mlclust

#endif  // MLCLUST_CORE_MESH_CONNECTIVITY_GUARD_H_
