// CVD mesh coarsening (section 3.1.4): the coarse triangle mesh that a face clustering
// describes, one vertex per cluster and triangles where clusters meet.
//
// The coarse mesh is the dual of the clusters' border graph. Its vertices are the clusters;
// its edges are the border arcs between two clusters; its faces are the "corners", the mesh
// vertices where three or more clusters meet. A corner where exactly three clusters meet
// gives one triangle; a corner of m > 3 clusters gives the polygon of its clusters in fan
// order, triangulated into m - 2 triangles.
//
// Open meshes: each boundary loop of the mesh is closed by a virtual region ("capped"), so
// a boundary vertex where the clusters change along the boundary is a corner of the two
// clusters and the loop. The dual is built on the capped surface, where the loop is a
// virtual vertex; removing those vertices with their triangles leaves a coarse boundary
// loop wherever the input has one that the clustering can show. A loop cannot be shown
// when it lies wholly inside one cluster, when a cluster meets it along two arcs, or when
// a cluster touches it and another loop (that cluster's vertex would lie on the coarse
// boundary twice): such a loop is closed over, its cap given to a cluster along it (a hole
// smaller than the clustering's resolution disappears; CoarseMesh::closed_boundary_loops).
//
// Untrusted-input safety: every index is checked before use and every walk is bounded, so
// a bad mesh or adjacency gives INVALID_ARGUMENT, never a crash; the clustering may be
// anything.
#ifndef MLCLUST_CORE_COARSENING_COARSENING_H_
#define MLCLUST_CORE_COARSENING_COARSENING_H_

#include <atomic>
#include <cstdint>
#include <span>
#include <vector>

#include "absl/status/statusor.h"
#include "core/base/ids.h"
#include "core/mesh/mesh.h"

namespace mlclust {

struct CoarseningOptions {
  enum class Placement {
    // The cluster's centroid, sum_j rho_j A_j g_j / sum_j rho_j A_j (eq. 3.6 / 3.22): with
    // `face_density` empty rho_j = 1 and this is the uniform CVD generator (l. 715); with the
    // densities of adaptive CVD or MWCVD it is the density-weighted centroid those
    // clusterings already have, which the text uses as the coarse vertex (l. 783, 937). The
    // plain mean of face centroids if the cluster's mass is 0.
    kCentroid,
    // The point minimising the cluster's Garland-Heckbert quadric: the sum over its faces
    // of A_j times the squared distance to face j's plane. The 3x3 system is solved by an
    // eigen-decomposition as a pseudo-inverse about the centroid: directions whose
    // eigenvalue is at most `quadric_relative_eigenvalue` times the largest are left
    // unconstrained and keep the centroid's coordinate. So a planar cluster's vertex is its
    // centroid (which lies on the plane), a cluster along a crease moves only across the
    // crease onto it, and a cluster around a corner gets the corner.
    kQuadric,
    // [VC04] (l. 763): the original mesh vertex closest to the centroid above, among the
    // vertices of the cluster's faces (ties to the lower vertex index).
    kClosestVertex,
  };
  Placement placement = Placement::kCentroid;
  // Per-face density rho_j (one positive finite value per face) for the centroid, e.g.
  // EnergyFaceDensity of the clustering's energy options; empty: rho_j = 1. Not owned: it
  // must outlive the call.
  std::span<const double> face_density;
  // Only for kQuadric: eigenvalues up to this fraction of the largest count as zero.
  double quadric_relative_eigenvalue = 1e-3;

  // A cluster that is not a disc (not edge-connected, touching itself at a vertex, with a
  // handle, or around a tube or other clusters) cannot be one manifold vertex. With repair
  // on, such a cluster's faces are re-grown, for the connectivity only, from its most
  // interior face as far as it stays a disc, and the faces it cannot take go to its
  // neighbours as far as they stay discs; this repeats for at most `max_repair_rounds`.
  // Vertex positions always come from the clusters as given. With repair off, such a
  // cluster is a FAILED_PRECONDITION error.
  bool repair_clusters = true;
  int max_repair_rounds = 8;

  // Checked between the steps (and repair rounds) of the coarsening (core/base/cancel.h);
  // a set flag returns CANCELLED.
  const std::atomic<bool>* cancel = nullptr;
};

struct CoarseMesh {
  TriangleMesh mesh;
  std::vector<ClusterId> vertex_cluster;  // the cluster of each coarse vertex
  uint32_t repaired_clusters = 0;         // clusters that were not discs and were re-grown
  uint32_t moved_faces = 0;               // faces the repair gave to another cluster
  uint32_t edge_flips = 0;                // flips that removed doubled coarse edges
  uint32_t closed_boundary_loops = 0;     // input boundary loops with no coarse boundary loop
};

// Builds the coarse mesh of the clustering `labels` (one ClusterId per face; any ids, not
// necessarily 0..k-1) of `mesh`, whose adjacency is `adjacency` (BuildFaceAdjacency).
//
// Expects a mesh that passed ValidateMesh and is consistently oriented. On success the
// result has exactly k vertices, k the number of distinct labels: coarse vertex i is the
// i-th distinct cluster in order of first appearance in `labels` (vertex_cluster). Its
// faces are counter-clockwise like the input's, every directed edge appears once, every
// vertex is used, and every vertex's faces form one fan: a valid manifold mesh, closed where
// the input is closed, with the input's Euler characteristic V - E + F plus one for each
// boundary loop closed over.
//
// Rules:
//   - Triangles: a corner whose face fan, walked counter-clockwise, meets the clusters
//     (c1, c2, c3) gives the triangle (c1, c2, c3). A corner of m > 3 clusters is
//     triangulated as the fan from one of them: the fan whose diagonals are not coarse
//     edges yet and, among those, have the least total length. At a boundary corner the
//     loop's virtual vertex gets the ear between the clusters on either side of the
//     boundary gap, so the coarse boundary runs straight from one to the other.
//   - Doubled edges and duplicate triangles: every border arc becomes its own coarse edge,
//     paired with the arc's other end. Two clusters that meet along two arcs, a cluster
//     that meets only two others (a thin cluster, or the tip of a protrusion), or two
//     corners that give the same three clusters in the same order all show up as two edges
//     between the same two vertices. Each such edge is flipped (the quad of its two
//     triangles takes the other diagonal) where the new diagonal is not an edge yet, after
//     flipping that one out of the way if need be (up to three deep). So no triangle or
//     directed edge is emitted twice, and the topology is kept. The same three clusters in
//     opposite orders are two different triangles (a sphere of three clusters gives a
//     two-triangle "pillow").
//   - A cluster next to two boundary loops has its edges to all but one flipped away where
//     possible; otherwise one of the loops, the shorter, is closed over (see above).
//
// Errors, with a message that names the cluster by its label value:
//   - INVALID_ARGUMENT: `labels` or `adjacency` does not have one entry per face, a label is
//     ClusterId::Invalid(), a vertex index or neighbour id is out of range, the adjacency
//     does not match the mesh, or an option is out of range.
//   - FAILED_PRECONDITION when the mesh is not consistently oriented, or the clustering has
//     no valid coarse mesh with k vertices that this function finds: a cluster that is not
//     a disc (with repair off, or still after the repair rounds); a cluster covering a
//     whole connected component; no corner at all (e.g. two clusters on a sphere); a
//     cluster on no corner; doubled edges no flip separates (fewer than three clusters
//     around a thin tube or handle: a closed triangle mesh needs three vertices around
//     every tube, and a torus needs seven in all).
//
// Time O(F + V) expected, plus O(territory) per repaired cluster and per repair round, and
// a rebuild of the dual per boundary loop closed over.
absl::StatusOr<CoarseMesh> CoarsenMeshWithReport(const TriangleMesh& mesh,
                                                 const FaceAdjacency& adjacency,
                                                 std::span<const ClusterId> labels,
                                                 const CoarseningOptions& options = {});

// CoarsenMeshWithReport's mesh alone.
absl::StatusOr<TriangleMesh> CoarsenMesh(const TriangleMesh& mesh, const FaceAdjacency& adjacency,
                                         std::span<const ClusterId> labels,
                                         const CoarseningOptions& options = {});

// The cluster of each coarse vertex: the distinct labels in order of first appearance.
std::vector<ClusterId> CoarseVertexClusters(std::span<const ClusterId> labels);

}  // namespace mlclust

#endif  // MLCLUST_CORE_COARSENING_COARSENING_H_
