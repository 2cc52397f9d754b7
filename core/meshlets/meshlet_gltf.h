// Meshlets in a glTF 2.0 binary file (.glb) (`mlclust mesh INPUT --meshlets FILE.glb`): the
// mesh, drawable by any glTF viewer, and the meshlets as buffer views an engine reads.
//
// One buffer (the GLB's BIN chunk), every view 4-byte aligned:
//   view 0  POSITION: float32 xyz per vertex (accessor 0, VEC3, with min and max)
//   view 1  indices: uint32, the meshlets' triangles as input vertex indices, meshlet by
//           meshlet (accessor 1, SCALAR); meshlet m's triangles are the 3 * triangle_count
//           indices after the 3 * (sum of the triangle counts of meshlets 0..m-1) first
//   view 2  meshlets: uint32 vertex_offset, triangle_offset (bytes into view 4),
//           vertex_count, triangle_count per meshlet (meshoptimizer's meshopt_Meshlet)
//   view 3  meshlet_vertices: uint32 input vertex indices
//   view 4  meshlet_triangles: uint8 local indices, 3 per triangle, runs padded to 4 bytes
//   view 5  triangle_faces: uint32, the input face of each meshlet triangle
//   view 6  bounds (when computed): 48 bytes per meshlet, meshopt_Bounds' layout (centre xyz,
//           radius, cone apex xyz, cone axis xyz, cone cutoff as float32; cone axis xyz and
//           cutoff as int8 SNORM)
// The mesh's primitive (mode 4, triangles) uses accessors 0 and 1; its `extras` hold
// "mlclust_meshlets": {"version": 1, "max_vertices", "max_triangles", "meshlet_count",
// "meshlets", "meshlet_vertices", "meshlet_triangles", "triangle_faces", "bounds" (the
// numbers of views 2-6; "bounds" absent without them)}, the layout of core/meshlets/
// meshlet_file.h in glTF's own terms.
#ifndef MLCLUST_CORE_MESHLETS_MESHLET_GLTF_H_
#define MLCLUST_CORE_MESHLETS_MESHLET_GLTF_H_

#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "core/mesh/mesh.h"
#include "core/meshlets/meshlets.h"

namespace mlclust {

// The .glb bytes of `mesh` (whose meshlets `meshlets` are) as described above.
// INVALID_ARGUMENT if meshlets does not hold every face of the mesh, or the file would pass
// glTF's 4 GiB.
absl::StatusOr<std::string> EncodeMeshletGlb(const TriangleMesh& mesh,
                                             const MeshletResult& meshlets, uint32_t max_vertices,
                                             uint32_t max_triangles);

// Writes EncodeMeshletGlb's bytes to `path`; UNAVAILABLE naming the path if it cannot.
absl::Status WriteMeshletGlb(const std::string& path, const TriangleMesh& mesh,
                             const MeshletResult& meshlets, uint32_t max_vertices,
                             uint32_t max_triangles);

}  // namespace mlclust

#endif  // MLCLUST_CORE_MESHLETS_MESHLET_GLTF_H_
