// Repairing non-manifold meshes so that they can be clustered (issue 13's --repair):
// non-manifold edges and vertices are split by duplicating vertices, never by removing or
// reordering faces, so face i of the result is face i of the input and every label and
// output refers to the input's faces.
//
// What is split:
//   - an edge shared by more than two faces is cut: each of those faces sees it as a
//     boundary edge (the pages of a book become separate sheets along the spine);
//   - then every vertex gets one copy per fan: the faces around it that are connected
//     through edges shared by exactly two faces, without crossing a cut edge. A bow-tie
//     vertex (two fans) becomes two vertices; the ends of a cut edge become one per fan.
// Two faces that end up on the same copies of both ends of a cut edge share that edge
// again (at most two can: a fan is a path or a cycle of faces, and only its two end faces
// have a free side), so nothing is cut further than needed for manifoldness.
//
// The result passes ValidateMesh. Vertex ids are kept: copy 0 of vertex v is v (the fan
// holding v's lowest (face, corner)); further copies are appended, in order of their first
// (face, corner), at the end of the vertex array with v's position. Unused vertices stay.
//
// Not repaired (INVALID_ARGUMENT, as ValidateMesh): faces repeating a vertex (degenerate
// faces cannot be kept in place and made valid), out-of-range indices, non-finite
// coordinates, sizes that are not whole triangles and vertices, an empty mesh. Orientation
// is left as it is: two faces on a shared edge may run it the same way, which ValidateMesh
// accepts and the energies do not need.
#ifndef MLCLUST_CORE_MESH_REPAIR_H_
#define MLCLUST_CORE_MESH_REPAIR_H_

#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "core/base/ids.h"
#include "core/mesh/mesh.h"

namespace mlclust {

// An input edge that bordered more than two faces.
struct NonManifoldEdge {
  VertexId a, b;              // a < b, input vertex ids
  std::vector<FaceId> faces;  // increasing
};

struct MeshRepairReport {
  // Every cut edge, by (a, b).
  std::vector<NonManifoldEdge> cut_edges;
  // Every input vertex that was given more than one copy (its faces formed several fans,
  // or an edge through it was cut), increasing.
  std::vector<VertexId> split_vertices;
  // For each appended vertex, input_vertices + i, the input vertex it copies.
  std::vector<VertexId> copy_of;
  // Faces whose corners now name a copy instead of the input vertex.
  uint64_t faces_changed = 0;

  bool changed() const { return !copy_of.empty(); }
  // One line for a user: counts and the first few places, e.g. "cut 2 non-manifold edges
  // (vertices 4-9: faces 1, 2, 7; ...), split 3 vertices (4, 9, 12) into 7 copies, 5 faces
  // re-indexed; face ids unchanged", or "nothing to repair: the mesh is manifold".
  std::string Summary(size_t max_listed = 5) const;
};

struct MeshRepairResult {
  TriangleMesh mesh;
  MeshRepairReport report;
};

// Splits non-manifold edges and vertices as the header says. O(F log F) for F faces;
// memory O(F). Errors: INVALID_ARGUMENT as ValidateMesh for everything but
// manifoldness (see above).
absl::StatusOr<MeshRepairResult> RepairNonManifold(const TriangleMesh& mesh);

}  // namespace mlclust

#endif  // MLCLUST_CORE_MESH_REPAIR_H_
