#include "core/mesh/repair.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "core/base/status_macros.h"

namespace mlclust {
namespace {

// Everything ValidateMesh checks except manifoldness: what cannot be repaired in place.
absl::Status CheckRepairable(const TriangleMesh& mesh) {
  MLCLUST_RETURN_IF_ERROR(CheckMeshArrays(mesh));
  // Repair adds at most two copies per corner, so the vertex count is bounded by
  // vertices + 3 faces.
  if (mesh.num_faces() > kMaxMeshElements ||
      mesh.num_vertices() + 3 * mesh.num_faces() > kMaxMeshElements) {
    return absl::InvalidArgumentError(absl::StrCat(
        "mesh too large to repair: ", mesh.num_faces(), " faces and ", mesh.num_vertices(),
        " vertices; at most ", kMaxMeshElements, " vertices after splitting"));
  }
  MLCLUST_RETURN_IF_ERROR(CheckVertexIndices(mesh));
  for (size_t face = 0; face < mesh.num_faces(); ++face) {
    const uint32_t* f = &mesh.indices[3 * face];
    if (f[0] == f[1] || f[1] == f[2] || f[0] == f[2]) {
      return absl::InvalidArgumentError(
          absl::StrCat("degenerate face ", face, ": vertices (", f[0], ", ", f[1], ", ", f[2],
                       ") repeat an index; repair keeps every face and cannot fix it"));
    }
  }
  for (size_t v = 0; v < mesh.num_vertices(); ++v) {
    const float* p = &mesh.positions[3 * v];
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
      return absl::InvalidArgumentError(absl::StrCat("vertex ", v, " has a non-finite coordinate (",
                                                     p[0], ", ", p[1], ", ", p[2], ")"));
    }
  }
  return absl::OkStatus();
}

// Union-find over the 3F corners (corner c is face c / 3, corner c % 3).
class Corners {
 public:
  explicit Corners(size_t n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), 0u); }
  uint32_t Find(uint32_t c) {
    while (parent_[c] != c) {
      parent_[c] = parent_[parent_[c]];
      c = parent_[c];
    }
    return c;
  }
  // The root is the smaller corner, so a class's root is its first (face, corner).
  void Join(uint32_t a, uint32_t b) {
    a = Find(a);
    b = Find(b);
    if (a == b) return;
    if (b < a) std::swap(a, b);
    parent_[b] = a;
  }

 private:
  std::vector<uint32_t> parent_;
};

}  // namespace

absl::StatusOr<MeshRepairResult> RepairNonManifold(const TriangleMesh& mesh) {
  MLCLUST_RETURN_IF_ERROR(CheckRepairable(mesh));
  const size_t num_faces = mesh.num_faces();
  const size_t num_corners = 3 * num_faces;
  const uint32_t* indices = mesh.indices.data();

  // Every face edge (corner c runs from its vertex to the next corner's), grouped by its
  // undirected vertex pair.
  struct HalfEdge {
    uint64_t key;     // min vertex << 32 | max vertex
    uint32_t corner;  // 3 face + edge
  };
  std::vector<HalfEdge> edges(num_corners);
  for (uint32_t c = 0; c < num_corners; ++c) {
    const uint32_t a = indices[c], b = indices[c - c % 3 + (c % 3 + 1) % 3];
    edges[c] = {uint64_t{std::min(a, b)} << 32 | std::max(a, b), c};
  }
  std::sort(edges.begin(), edges.end(), [](const HalfEdge& x, const HalfEdge& y) {
    return x.key != y.key ? x.key < y.key : x.corner < y.corner;
  });

  // Glue the two faces of every edge with exactly two (their corners at each end are one
  // vertex); cut every edge with more (no gluing at all across it).
  MeshRepairResult result;
  Corners corners(num_corners);
  auto corner_at = [&](uint32_t face, uint32_t vertex) {
    for (uint32_t k = 0; k < 3; ++k) {
      if (indices[3 * face + k] == vertex) return 3 * face + k;
    }
    return uint32_t{0};  // unreachable: the face holds the vertex
  };
  for (size_t begin = 0; begin < edges.size();) {
    size_t end = begin + 1;
    while (end < edges.size() && edges[end].key == edges[begin].key) ++end;
    const uint32_t a = static_cast<uint32_t>(edges[begin].key >> 32);
    const uint32_t b = static_cast<uint32_t>(edges[begin].key);
    if (end - begin == 2) {
      const uint32_t f = edges[begin].corner / 3, g = edges[begin + 1].corner / 3;
      corners.Join(corner_at(f, a), corner_at(g, a));
      corners.Join(corner_at(f, b), corner_at(g, b));
    } else if (end - begin > 2) {
      NonManifoldEdge cut{VertexId(a), VertexId(b), {}};
      for (size_t e = begin; e < end; ++e) cut.faces.push_back(FaceId(edges[e].corner / 3));
      cut.faces.erase(std::unique(cut.faces.begin(), cut.faces.end()), cut.faces.end());
      result.report.cut_edges.push_back(std::move(cut));
    }
    begin = end;
  }

  // One vertex per corner class. Classes are met in corner order, so the first class of a
  // vertex (copy 0, which keeps the vertex id) is the one of its lowest corner.
  const uint32_t input_vertices = static_cast<uint32_t>(mesh.num_vertices());
  result.mesh.positions = mesh.positions;
  result.mesh.indices.resize(num_corners);
  std::vector<uint32_t> vertex_of_root(num_corners, FaceId::kInvalidValue);
  std::vector<bool> vertex_used(input_vertices, false), vertex_split(input_vertices, false);
  std::vector<bool> face_changed(num_faces, false);
  for (uint32_t c = 0; c < num_corners; ++c) {
    const uint32_t root = corners.Find(c);
    uint32_t& vertex = vertex_of_root[root];
    if (vertex == FaceId::kInvalidValue) {
      const uint32_t v = indices[c];
      if (!vertex_used[v]) {
        vertex_used[v] = true;
        vertex = v;
      } else {
        vertex_split[v] = true;
        vertex = input_vertices + static_cast<uint32_t>(result.report.copy_of.size());
        result.report.copy_of.push_back(VertexId(v));
        const float* p = &mesh.positions[3 * size_t{v}];
        result.mesh.positions.insert(result.mesh.positions.end(), p, p + 3);
      }
    }
    result.mesh.indices[c] = vertex;
    if (vertex != indices[c]) face_changed[c / 3] = true;
  }
  for (uint32_t v = 0; v < input_vertices; ++v) {
    if (vertex_split[v]) result.report.split_vertices.push_back(VertexId(v));
  }
  result.report.faces_changed =
      static_cast<uint64_t>(std::count(face_changed.begin(), face_changed.end(), true));

  // The header's argument says this cannot fail; a failure is our bug, not the input's.
  // Where nothing was split, every edge had at most two faces and every vertex one fan, and
  // the checks above are ValidateMesh's others: the input was valid, so is the copy.
  if (!result.report.changed()) return result;
  if (absl::Status valid = ValidateMesh(result.mesh); !valid.ok()) {
    return absl::InternalError(
        absl::StrCat("repair left a mesh that does not validate: ", valid.message()));
  }
  return result;
}

std::string MeshRepairReport::Summary(size_t max_listed) const {
  if (!changed()) return "nothing to repair: the mesh is manifold";
  std::string out;
  if (!cut_edges.empty()) {
    std::vector<std::string> listed;
    for (size_t i = 0; i < cut_edges.size() && i < max_listed; ++i) {
      std::vector<uint32_t> faces;
      for (FaceId f : cut_edges[i].faces) faces.push_back(f.value());
      listed.push_back(absl::StrCat("vertices ", cut_edges[i].a.value(), "-",
                                    cut_edges[i].b.value(), ": faces ",
                                    absl::StrJoin(faces, ", ")));
    }
    absl::StrAppend(&out, "cut ", cut_edges.size(), " non-manifold edge",
                    cut_edges.size() == 1 ? "" : "s", " (", absl::StrJoin(listed, "; "),
                    cut_edges.size() > max_listed ? "; ..." : "", "), ");
  }
  std::vector<uint32_t> listed;
  for (size_t i = 0; i < split_vertices.size() && i < max_listed; ++i) {
    listed.push_back(split_vertices[i].value());
  }
  absl::StrAppend(&out, "split ", split_vertices.size(), " ",
                  split_vertices.size() == 1 ? "vertex" : "vertices", " (",
                  absl::StrJoin(listed, ", "), split_vertices.size() > max_listed ? ", ..." : "",
                  ") into ", split_vertices.size() + copy_of.size(), " copies, ", faces_changed,
                  " face", faces_changed == 1 ? "" : "s", " re-indexed; face ids unchanged");
  return out;
}

}  // namespace mlclust
