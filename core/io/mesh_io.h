// Reading meshes from the files asset pipelines use, and writing clustered results.
#ifndef MLCLUST_CORE_IO_MESH_IO_H_
#define MLCLUST_CORE_IO_MESH_IO_H_

#include <array>
#include <cstdint>
#include <span>
#include <string>

#include "absl/status/statusor.h"
#include "core/base/ids.h"
#include "core/mesh/mesh.h"

namespace mlclust {

// Reads a triangle mesh. `.drc` files (or files starting with Draco's magic) are decoded
// with Draco; OFF files (by extension or keyword) are read by our own strict reader,
// because Assimp's silently clamps bad indices and drops large polygons; every other
// format goes through Assimp (OBJ, PLY, STL, glTF/GLB and the rest it reads). glTF/GLB
// primitives compressed with KHR_draco_mesh_compression are decoded with Draco first
// (vertex i of such a primitive is Draco point i, its faces in the Draco data's order).
//
// Faces keep file order: face i of the result is the i-th triangle of the file, which is
// the id every output uses. A polygon of n corners becomes n - 2 triangles in its place
// (ear clipping; a convex polygon becomes the fan around its first corner), keeping its
// winding; triangles keep their corners exactly as written. Points and lines are dropped.
// Meshes are placed by the scene's node tree (glTF and the like), walked depth first in
// file order; a mesh used by two nodes appears twice, and a mirroring node transform has
// its triangles' winding restored. Untransformed positions are copied bit for bit.
//
// Vertices: a mesh that indexes shared vertices (OFF, PLY, glTF with indices, Draco)
// keeps its vertices as written, unused ones included, so that vertex i of a one-mesh
// file is its vertex i; vertices at one position stay distinct, as the file says. Where
// no two polygons share a vertex (STL stores a corner per face; Assimp's OBJ reader
// expands every corner), vertices at exactly the same position are welded, across
// meshes too, in first-seen order, and unused ones are dropped.
//
// NOT_FOUND if the file is missing; INVALID_ARGUMENT, naming the file, if it cannot be
// parsed or holds no triangles; the errno-derived code (e.g. PERMISSION_DENIED) if it
// cannot be read. The result is not validated: call ValidateMesh.
//
// Meant for the operator's own files. Assimp is not hardened against hostile input (the
// Debian build keeps its internal assertions, which abort the process, and its PLY
// reader loops forever on a truncated header unless, as here, the header is checked
// first); bytes from the network go through DecodeDracoMesh.
absl::StatusOr<TriangleMesh> ReadMeshFile(const std::string& path);

struct ClusteredPlyOptions {
  // false (the default): the input's vertices, one to one, unsplit, without colour.
  // true: each vertex is written once per cluster among the faces around it, each copy
  // with its cluster's colour as a vertex colour (for viewers that draw only vertex
  // colours, e.g. Blender); face indices then refer to the copies.
  bool split_vertices = false;
};

// Writes `mesh` as binary little-endian PLY with the clusters as face properties:
//
//   element vertex V          property float x, y, z   (uchar red, green, blue when split)
//   element face F            property list uchar int vertex_indices
//                             property int cluster      labels[f]; -1 for ClusterId::Invalid()
//                             property uchar red, green, blue   ClusterColour(labels[f])
//
// Faces keep their order, so face f of the file is face f of `mesh`; without
// split_vertices, vertex v of the file is vertex v of `mesh` (unused ones included) and
// positions are copied bit for bit. `labels` has one entry per face. INVALID_ARGUMENT
// for another count, a vertex index out of range or a cluster id above 2^31 - 1; the
// file's errno-derived error if it cannot be written.
absl::Status WriteClusteredPly(const std::string& path, const TriangleMesh& mesh,
                               std::span<const ClusterId> labels,
                               const ClusteredPlyOptions& options = {});

// Writes `mesh` as glTF 2.0 with the clusters as vertex attributes, by the path's
// extension: .glb (binary) or .gltf (JSON, the buffer embedded as a base64 data: URI).
// One mesh with one triangle primitive:
//
//   POSITION   float VEC3
//   COLOR_0    unsigned byte normalized VEC4: ClusterColour(labels[f]), opaque (grey for
//              ClusterId::Invalid())
//   _CLUSTER   float SCALAR: labels[f], -1 for ClusterId::Invalid() (an application-
//              specific attribute, glTF 2.0 3.7.2.1; float, as core glTF vertex
//              attributes are float or normalized integers: ids below 2^24 are exact)
//   indices    uint32; triangle f is face f of `mesh`
//
// glTF attributes belong to vertices, so each vertex is written once per cluster among
// the faces around it, and all three corners of face f carry labels[f]. Positions are
// copied bit for bit. INVALID_ARGUMENT for a label count other than one per face, a
// vertex index out of range, a non-finite coordinate, a cluster id of 2^24 or more, or
// another extension; the file's errno-derived error if it cannot be written.
absl::Status WriteClusteredGltf(const std::string& path, const TriangleMesh& mesh,
                                std::span<const ClusterId> labels);

// Writes `mesh` by the path's extension: .ply (binary little-endian), .obj or .off. Face
// and vertex order are kept. INVALID_ARGUMENT for another extension or indices out of
// range; UNAVAILABLE if the file cannot be written.
absl::Status WriteMeshFile(const std::string& path, const TriangleMesh& mesh);

// A colour for cluster `id`, well spread over hue, stable for a given id.
std::array<uint8_t, 3> ClusterColour(uint32_t id);

}  // namespace mlclust

#endif  // MLCLUST_CORE_IO_MESH_IO_H_
