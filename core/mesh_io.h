// Reading meshes from the files asset pipelines use, and writing clustered results.
#ifndef MLCLUST_CORE_MESH_IO_H_
#define MLCLUST_CORE_MESH_IO_H_

#include <array>
#include <cstdint>
#include <span>
#include <string>

#include "absl/status/statusor.h"
#include "core/ids.h"
#include "core/mesh.h"

namespace mlclust {

// Reads a triangle mesh. `.drc` files are decoded with Draco; every other format goes
// through Assimp (OBJ, PLY, OFF, STL, glTF/GLB and the rest it reads). Polygons are
// triangulated by Assimp; all meshes of a scene are concatenated in scene order; points
// and lines are dropped. Vertices at exactly the same position are welded (formats such
// as STL store a corner per face), keeping first-seen order. Faces keep file order: face
// i of the result is the i-th triangle of the file, which is the id every output uses.
// NOT_FOUND if the file is missing; INVALID_ARGUMENT, naming the file, if it cannot be
// parsed or holds no triangles. The result is not validated: call ValidateMesh.
absl::StatusOr<TriangleMesh> ReadMeshFile(const std::string& path);

// Writes `mesh` as binary PLY with one colour per cluster: each face gets its cluster's
// colour as a face colour (MeshLab) and its vertices are split per cluster so that vertex
// colours show the same (Blender). `labels` has one entry per face.
absl::Status WriteClusteredPly(const std::string& path, const TriangleMesh& mesh,
                               std::span<const ClusterId> labels);

// A colour for cluster `id`, well spread over hue, stable for a given id.
std::array<uint8_t, 3> ClusterColour(uint32_t id);

}  // namespace mlclust

#endif  // MLCLUST_CORE_MESH_IO_H_
