#include "core/mesh/mesh.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "core/base/cancel.h"
#include "core/base/status_macros.h"

namespace mlclust {
namespace {

// The table of mesh.h, with pointer access for the hot loops below.
struct VertexFaces {
  VertexFaceTable table;
  const uint32_t* begin(uint32_t v) const { return table.faces.data() + table.offset[v]; }
  const uint32_t* end(uint32_t v) const { return table.faces.data() + table.offset[v + 1]; }
};

VertexFaces BuildVertexFaces(const TriangleMesh& mesh) { return {BuildVertexFaceTable(mesh)}; }

bool FaceHasVertex(const TriangleMesh& mesh, uint32_t face, uint32_t vertex) {
  const uint32_t* f = &mesh.indices[3 * static_cast<size_t>(face)];
  return f[0] == vertex || f[1] == vertex || f[2] == vertex;
}

// Checks that the faces around `vertex` form a single fan: connected through the edges
// that contain the vertex. A vertex whose faces form two fans (a bow-tie) is non-manifold.
absl::Status CheckVertexManifold(const TriangleMesh& mesh, const VertexFaces& table,
                                 const FaceAdjacency& adjacency, uint32_t vertex,
                                 std::vector<uint32_t>& component) {
  const uint32_t* first = table.begin(vertex);
  const size_t degree = table.end(vertex) - first;
  if (degree <= 1) return absl::OkStatus();
  // Flood from the first face over neighbours that also contain the vertex.
  component.assign(degree, 0);
  std::vector<size_t> stack = {0};
  component[0] = 1;
  size_t reached = 1;
  while (!stack.empty()) {
    const uint32_t face = first[stack.back()];
    stack.pop_back();
    for (FaceId neighbour : adjacency.neighbours[face]) {
      if (!neighbour.valid() || !FaceHasVertex(mesh, neighbour.value(), vertex)) continue;
      for (size_t k = 0; k < degree; ++k) {
        if (first[k] == neighbour.value() && component[k] == 0) {
          component[k] = 1;
          ++reached;
          stack.push_back(k);
        }
      }
    }
  }
  if (reached == degree) return absl::OkStatus();
  std::vector<uint32_t> fan, other;
  for (size_t k = 0; k < degree; ++k) (component[k] ? fan : other).push_back(first[k]);
  return absl::InvalidArgumentError(
      absl::StrCat("non-manifold vertex ", vertex, ": its faces form more than one fan (faces ",
                   absl::StrJoin(fan, ", "), " are not edge-connected around it to faces ",
                   absl::StrJoin(other, ", "), ")"));
}

// Loops over faces or vertices look at the cancel flag once per this many elements.
constexpr uint32_t kElementsPerCancelCheck = 65536;

absl::Status CheckCancelledAt(const std::atomic<bool>* cancel, size_t element,
                              absl::string_view where) {
  if (element % kElementsPerCancelCheck != 0) return absl::OkStatus();
  return CheckCancelled(cancel, where);
}

absl::StatusOr<FaceAdjacency> BuildFaceAdjacencyFrom(const TriangleMesh& mesh,
                                                     const VertexFaces& table,
                                                     const std::atomic<bool>* cancel) {
  FaceAdjacency adjacency;
  const size_t num_faces = mesh.num_faces();
  adjacency.neighbours.assign(num_faces, {FaceId::Invalid(), FaceId::Invalid(), FaceId::Invalid()});
  for (uint32_t face = 0; face < num_faces; ++face) {
    MLCLUST_RETURN_IF_ERROR(CheckCancelledAt(cancel, face, "face adjacency"));
    for (int edge = 0; edge < 3; ++edge) {
      const uint32_t a = mesh.indices[3 * size_t{face} + edge];
      const uint32_t b = mesh.indices[3 * size_t{face} + (edge + 1) % 3];
      // Scan the faces around the endpoint with fewer faces for others holding both ends.
      const uint32_t pivot =
          (table.end(a) - table.begin(a)) <= (table.end(b) - table.begin(b)) ? a : b;
      const uint32_t other_end = pivot == a ? b : a;
      uint32_t found = FaceId::kInvalidValue;
      for (const uint32_t* it = table.begin(pivot); it != table.end(pivot); ++it) {
        if (*it == face || !FaceHasVertex(mesh, *it, other_end)) continue;
        if (found != FaceId::kInvalidValue && found != *it) {
          return absl::InvalidArgumentError(absl::StrCat(
              "non-manifold edge between vertices ", a, " and ", b, ": shared by faces ", face,
              ", ", found, " and ", *it, " (an edge may border at most two faces)"));
        }
        found = *it;
      }
      adjacency.neighbours[face][edge] = FaceId(found);
    }
  }
  return adjacency;
}

}  // namespace

VertexFaceTable BuildVertexFaceTable(const TriangleMesh& mesh) {
  VertexFaceTable table;
  const size_t num_vertices = mesh.num_vertices();
  table.offset.assign(num_vertices + 1, 0);
  for (uint32_t v : mesh.indices) ++table.offset[v + 1];
  std::partial_sum(table.offset.begin(), table.offset.end(), table.offset.begin());
  table.faces.resize(mesh.indices.size());
  std::vector<uint32_t> cursor(table.offset.begin(), table.offset.end() - 1);
  for (size_t i = 0; i < mesh.indices.size(); ++i) {
    table.faces[cursor[mesh.indices[i]]++] = static_cast<uint32_t>(i / 3);
  }
  return table;
}

absl::StatusOr<FaceAdjacency> BuildFaceAdjacency(const TriangleMesh& mesh,
                                                 const std::atomic<bool>* cancel) {
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(cancel, "face adjacency"));
  return BuildFaceAdjacencyFrom(mesh, BuildVertexFaces(mesh), cancel);
}

absl::Status CheckVertexIndices(const TriangleMesh& mesh) {
  const size_t num_vertices = mesh.num_vertices();
  for (size_t i = 0; i < mesh.indices.size(); ++i) {
    if (mesh.indices[i] >= num_vertices) {
      return absl::InvalidArgumentError(
          absl::StrCat("face ", i / 3, " corner ", i % 3, ": vertex index ", mesh.indices[i],
                       " is out of range (the mesh has ", num_vertices, " vertices)"));
    }
  }
  return absl::OkStatus();
}

absl::Status CheckMeshArrays(const TriangleMesh& mesh) {
  if (mesh.positions.size() % 3 != 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("positions hold ", mesh.positions.size(), " floats, not a multiple of 3"));
  }
  if (mesh.indices.size() % 3 != 0) {
    return absl::InvalidArgumentError(absl::StrCat(
        "indices hold ", mesh.indices.size(), " values, not a multiple of 3 (triangles only)"));
  }
  if (mesh.num_faces() == 0) return absl::InvalidArgumentError("empty mesh: it has no faces");
  return absl::OkStatus();
}

absl::StatusOr<FaceAdjacency> ValidateMeshAndBuildAdjacency(const TriangleMesh& mesh,
                                                            const std::atomic<bool>* cancel) {
  MLCLUST_RETURN_IF_ERROR(CheckMeshArrays(mesh));
  if (mesh.num_faces() > kMaxMeshElements || mesh.num_vertices() > kMaxMeshElements) {
    return absl::InvalidArgumentError(
        absl::StrCat("mesh too large: ", mesh.num_faces(), " faces and ", mesh.num_vertices(),
                     " vertices; at most ", kMaxMeshElements, " of each"));
  }
  const size_t num_vertices = mesh.num_vertices();
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(cancel, "mesh validation"));
  MLCLUST_RETURN_IF_ERROR(CheckVertexIndices(mesh));
  for (size_t face = 0; face < mesh.num_faces(); ++face) {
    MLCLUST_RETURN_IF_ERROR(CheckCancelledAt(cancel, face, "mesh validation"));
    const uint32_t* f = &mesh.indices[3 * face];
    if (f[0] == f[1] || f[1] == f[2] || f[0] == f[2]) {
      return absl::InvalidArgumentError(absl::StrCat("degenerate face ", face, ": vertices (", f[0],
                                                     ", ", f[1], ", ", f[2], ") repeat an index"));
    }
  }
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(cancel, "mesh validation"));
  for (size_t v = 0; v < num_vertices; ++v) {
    const float* p = &mesh.positions[3 * v];
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
      return absl::InvalidArgumentError(absl::StrCat("vertex ", v, " has a non-finite coordinate (",
                                                     p[0], ", ", p[1], ", ", p[2], ")"));
    }
  }
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(cancel, "mesh validation"));
  const VertexFaces table = BuildVertexFaces(mesh);
  MLCLUST_ASSIGN_OR_RETURN(FaceAdjacency adjacency, BuildFaceAdjacencyFrom(mesh, table, cancel));
  std::vector<uint32_t> scratch;
  for (uint32_t v = 0; v < num_vertices; ++v) {
    MLCLUST_RETURN_IF_ERROR(CheckCancelledAt(cancel, v, "mesh validation"));
    MLCLUST_RETURN_IF_ERROR(CheckVertexManifold(mesh, table, adjacency, v, scratch));
  }
  return adjacency;
}

absl::Status ValidateMesh(const TriangleMesh& mesh, const std::atomic<bool>* cancel) {
  return ValidateMeshAndBuildAdjacency(mesh, cancel).status();
}

uint32_t LabelFaceComponents(const FaceAdjacency& adjacency, std::vector<uint32_t>& component,
                             std::span<const uint32_t> region) {
  // A component is a cluster of faces: "not labelled yet" is ClusterId's sentinel.
  const size_t n = adjacency.num_faces();
  component.assign(n, ClusterId::kInvalidValue);
  std::vector<uint32_t> stack;
  uint32_t count = 0;
  for (uint32_t start = 0; start < n; ++start) {
    if (component[start] != ClusterId::kInvalidValue) continue;
    component[start] = count;
    stack.push_back(start);
    while (!stack.empty()) {
      const uint32_t face = stack.back();
      stack.pop_back();
      for (FaceId neighbour : adjacency.neighbours[face]) {
        if (!neighbour.valid() || component[neighbour.value()] != ClusterId::kInvalidValue)
          continue;
        if (!region.empty() && region[neighbour.value()] != region[face]) continue;
        component[neighbour.value()] = count;
        stack.push_back(neighbour.value());
      }
    }
    ++count;
  }
  return count;
}

size_t CountFaceComponents(const FaceAdjacency& adjacency) {
  std::vector<uint32_t> component;
  return LabelFaceComponents(adjacency, component);
}

}  // namespace mlclust
