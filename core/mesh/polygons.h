// The input's polygons (issue 13): a quad or n-gon mesh arrives triangulated, each polygon
// as a run of consecutive triangles (the readers of core/io/mesh_io.h turn a polygon of n
// corners into n - 2 triangles in its place). Given the number of triangles of every
// polygon, the algorithms treat a polygon as one element (ours, an option: the
// dissertation's elements are triangles): a polygon's sums are the sums of its triangles
// (every energy's sums are additive), polygons neighbour across triangle edges, and the
// connectivity guard's ring of a polygon is the ring of faces around its boundary.
#ifndef MLCLUST_CORE_MESH_POLYGONS_H_
#define MLCLUST_CORE_MESH_POLYGONS_H_

#include <atomic>
#include <cstdint>
#include <span>
#include <vector>

#include "absl/status/statusor.h"
#include "core/base/ids.h"
#include "core/mesh/connectivity_guard.h"
#include "core/mesh/mesh.h"

namespace mlclust {

// Neighbour lists of any length in compressed rows: row i is ids[offset[i] .. offset[i+1]).
// Read as FaceAdjacency::neighbours is (`for (FaceId g : neighbours[i])`), so the drivers
// that are templates over the adjacency run on polygons unchanged; FaceId here is the
// element's (polygon's) index and every entry is valid.
struct NeighbourRows {
  std::vector<uint32_t> offset = {0};
  std::vector<FaceId> ids;
  std::span<const FaceId> operator[](size_t row) const {
    return {ids.data() + offset[row], ids.data() + offset[row + 1]};
  }
  size_t size() const { return offset.size() - 1; }
};

// The polygons' dual graph: for each polygon, the distinct polygons across its triangles'
// edges, in order of first appearance (the polygon's triangles flooded from its first,
// each triangle's edges in order), so polygons of one triangle have the faces' order.
struct PolygonAdjacency {
  NeighbourRows neighbours;
  size_t num_faces() const { return neighbours.size(); }  // polygons; the drivers' name
};

struct MeshPolygons {
  // Polygon p is the faces first_face[p] .. first_face[p + 1] - 1 (num_polygons() + 1
  // entries, the last the face count).
  std::vector<uint32_t> first_face;
  std::vector<uint32_t> polygon_of_face;  // one per face
  PolygonAdjacency adjacency;

  size_t num_polygons() const { return first_face.size() - 1; }
  size_t num_faces() const { return polygon_of_face.size(); }
  uint32_t triangles(uint32_t polygon) const {
    return first_face[polygon + 1] - first_face[polygon];
  }
};

// The polygons of a mesh from the number of triangles of each, in face order (the wire's
// JobSpec.polygon_triangle_counts). Untrusted input: INVALID_ARGUMENT naming the index for
// an empty list, a count of 0, counts that do not add up to the mesh's faces (or exceed
// them part-way), or a polygon whose triangles are not edge-connected. `adjacency` is the
// mesh's face adjacency.
absl::StatusOr<MeshPolygons> MakeMeshPolygons(std::span<const uint32_t> triangle_counts,
                                              const FaceAdjacency& adjacency);

// The ring test of core/mesh/connectivity_guard.h on polygons: the ring of polygon p is
// the faces outside p that share a vertex with it, in order around p's boundary (kGap
// where the mesh border breaks it), each replaced by its polygon. So moving a polygon
// from A to B is allowed iff A keeps another polygon and A and B each meet the ring in
// exactly one run: the simple-point test, for a disc of triangles instead of one. A
// polygon whose boundary is not one simple loop (a pinched polygon, which a triangulated
// n-gon never is) gets an empty ring and never moves. CanMove takes polygon labels and
// sizes in polygons. CANCELLED if `cancel` is set (checked every few thousand polygons).
absl::StatusOr<ConnectivityGuard> BuildPolygonConnectivityGuard(const TriangleMesh& mesh,
                                                                const FaceAdjacency& adjacency,
                                                                const MeshPolygons& polygons,
                                                                const std::atomic<bool>* cancel);

// Per-face labels from per-polygon ones (each triangle gets its polygon's).
std::vector<ClusterId> FaceLabelsOfPolygons(const MeshPolygons& polygons,
                                            std::span<const uint32_t> polygon_labels);

// Per-polygon labels from per-face ones; INVALID_ARGUMENT naming the polygon whose
// triangles are in two clusters, or for labels not one per face.
absl::StatusOr<std::vector<ClusterId>> PolygonLabelsOfFaces(const MeshPolygons& polygons,
                                                            std::span<const ClusterId> face_labels);

}  // namespace mlclust

#endif  // MLCLUST_CORE_MESH_POLYGONS_H_
