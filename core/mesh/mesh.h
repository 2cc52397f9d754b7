// Triangle meshes: storage, validation and face adjacency.
//
// A TriangleMesh is an indexed face set: three float coordinates per vertex and three
// vertex indices per face. Face order is the caller's order and is never changed by
// anything in core: a face's index is its id on the wire and in every output.
#ifndef MLCLUST_CORE_MESH_MESH_H_
#define MLCLUST_CORE_MESH_MESH_H_

#include <array>
#include <atomic>
#include <cstdint>
#include <span>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "core/base/ids.h"
#include "core/base/vec3.h"

namespace mlclust {

struct TriangleMesh {
  std::vector<float> positions;   // x, y, z per vertex
  std::vector<uint32_t> indices;  // three vertex indices per face, counter-clockwise

  size_t num_vertices() const { return positions.size() / 3; }
  size_t num_faces() const { return indices.size() / 3; }
  VertexId corner(FaceId face, int corner) const {
    return VertexId(indices[3 * static_cast<size_t>(face.value()) + corner]);
  }
  Vec3 position(VertexId vertex) const {
    const float* p = &positions[3 * static_cast<size_t>(vertex.value())];
    return {p[0], p[1], p[2]};
  }
};

// The most faces (and vertices) a mesh may have: ids are 32-bit and kInvalid is reserved.
inline constexpr size_t kMaxMeshElements = (size_t{1} << 31) - 1;

// Checks everything that arrives from a file or the wire before any algorithm sees it.
// Returns OK, or INVALID_ARGUMENT with a message that names the problem and where:
//   - empty mesh (no faces), or a positions/indices array whose size is not a multiple of 3;
//   - more than kMaxMeshElements faces or vertices;
//   - a vertex index out of range (which face, which corner);
//   - a degenerate face (a vertex index repeated within the face);
//   - a non-finite coordinate (which vertex);
//   - a non-manifold edge (an edge shared by more than two faces: which faces);
//   - a non-manifold vertex (the faces around it form more than one fan).
// Zero-area faces with three distinct vertices and unreferenced vertices are accepted.
// CANCELLED if `cancel` (core/base/cancel.h) is set, checked every few thousand elements.
absl::Status ValidateMesh(const TriangleMesh& mesh, const std::atomic<bool>* cancel = nullptr);

// The range check alone: OK, or INVALID_ARGUMENT naming the first face corner whose
// vertex index is not below num_vertices(). Part of ValidateMesh; for writers and encoders
// that must not index out of bounds but accept what ValidateMesh would refuse.
absl::Status CheckVertexIndices(const TriangleMesh& mesh);

// The array shape alone: OK, or INVALID_ARGUMENT for positions or indices that are not whole
// triples, or no face. Part of ValidateMesh (and of RepairNonManifold's precondition).
absl::Status CheckMeshArrays(const TriangleMesh& mesh);

// The faces around each vertex, in compressed rows: the faces of vertex v are
// faces[offset[v] .. offset[v + 1]), in increasing face order. Built by a counting sort in
// O(faces + vertices); expects indices in range.
struct VertexFaceTable {
  std::vector<uint32_t> offset;
  std::vector<uint32_t> faces;

  std::span<const uint32_t> faces_around(uint32_t vertex) const {
    return {faces.data() + offset[vertex], faces.data() + offset[vertex + 1]};
  }
};
VertexFaceTable BuildVertexFaceTable(const TriangleMesh& mesh);

// For each face, the face across each of its three edges; edge i runs from corner i to
// corner (i + 1) % 3. FaceId::Invalid() across a boundary edge.
struct FaceAdjacency {
  std::vector<std::array<FaceId, 3>> neighbours;

  size_t num_faces() const { return neighbours.size(); }
};

// Builds face adjacency in O(faces + vertices) time through a vertex-to-face table.
// Expects indices in range and no degenerate face (ValidateMesh checks both); returns
// INVALID_ARGUMENT naming the faces if an edge borders more than two faces; CANCELLED if
// `cancel` is set.
absl::StatusOr<FaceAdjacency> BuildFaceAdjacency(const TriangleMesh& mesh,
                                                 const std::atomic<bool>* cancel = nullptr);

// ValidateMesh and, for a valid mesh, the adjacency it builds on the way (what
// BuildFaceAdjacency would return), in one pass instead of two.
absl::StatusOr<FaceAdjacency> ValidateMeshAndBuildAdjacency(
    const TriangleMesh& mesh, const std::atomic<bool>* cancel = nullptr);

// Number of edge-connected components of the face graph.
size_t CountFaceComponents(const FaceAdjacency& adjacency);

// The one component flood: component[f] = the edge-connected component of face f,
// numbered 0.. in order of each component's smallest face; returns the count. With
// `region` (one id per face, optional), faces connect only across edges whose two faces
// have the same id, so the components are the edge-connected pieces of each region (a
// cluster in two pieces gives two components).
uint32_t LabelFaceComponents(const FaceAdjacency& adjacency, std::vector<uint32_t>& component,
                             std::span<const uint32_t> region = {});

}  // namespace mlclust

#endif  // MLCLUST_CORE_MESH_MESH_H_
