// The meshlet file (`mlclust mesh INPUT --meshlets FILE`): BuildMeshlets' result as one
// little-endian binary file that an engine can map and upload as it is.
//
//   offset  size              field
//   0       8                 magic "MLCMSHLT"
//   8       4   uint32        version (1)
//   12      4   uint32        header bytes (64): the arrays start here
//   16      4   uint32        max_vertices the meshlets were built with
//   20      4   uint32        max_triangles the meshlets were built with
//   24      4   uint32        meshlet count M
//   28      4   uint32        meshlet vertex entries N (length of meshlet_vertices)
//   32      4   uint32        meshlet triangle bytes B (length of meshlet_triangles, 4 | B)
//   36      4   uint32        face count F (the input mesh's faces)
//   40      4   uint32        vertex count V (the input mesh's vertices)
//   44      4   uint32        flags: bit 0 = bounds present
//   48      16                zero (a reader refuses other bytes)
//   64      16 M              meshlets: vertex_offset, triangle_offset (bytes), vertex_count,
//                             triangle_count, uint32 each (meshopt_Meshlet)
//   ..      4 N               meshlet_vertices: uint32 input vertex indices
//   ..      B                 meshlet_triangles: uint8 local indices, 3 per triangle, each
//                             meshlet's run padded with zeros to 4 bytes
//   ..      4 F               triangle_faces: uint32, the input face of each meshlet triangle,
//                             meshlet by meshlet (so that face attributes can follow)
//   ..      48 M (flag 0)     bounds: center xyz, radius, cone_apex xyz, cone_axis xyz,
//                             cone_cutoff (float32 each), cone_axis_s8 xyz, cone_cutoff_s8
//                             (int8 each): meshopt_Bounds' layout
//
// Every section starts at a multiple of 4 bytes. The file does not hold positions: the
// vertex indices are the input mesh's.
#ifndef MLCLUST_CORE_MESHLETS_MESHLET_FILE_H_
#define MLCLUST_CORE_MESHLETS_MESHLET_FILE_H_

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "core/meshlets/meshlets.h"

namespace mlclust {

inline constexpr char kMeshletFileMagic[8] = {'M', 'L', 'C', 'M', 'S', 'H', 'L', 'T'};
inline constexpr uint32_t kMeshletFileVersion = 1;
inline constexpr uint32_t kMeshletFileHeaderBytes = 64;

// What a meshlet file holds.
struct MeshletFile {
  uint32_t max_vertices = 0;
  uint32_t max_triangles = 0;
  uint32_t vertex_count = 0;  // of the input mesh
  MeshletResult meshlets;     // face_meshlet rebuilt from triangle_faces
};

// The file's bytes for `meshlets`, built from a mesh of `vertex_count` vertices with these
// caps. INVALID_ARGUMENT if an array is longer than 32 bits can count.
absl::StatusOr<std::string> EncodeMeshletFile(const MeshletResult& meshlets, uint32_t vertex_count,
                                              uint32_t max_vertices, uint32_t max_triangles);

// Parses and checks a meshlet file's bytes: the magic, version, zero reserved bytes, sizes
// that add up to the byte count, and the layout (offsets, counts, local indices, caps, each
// face once, vertex indices below V, zero padding). What it accepts, EncodeMeshletFile
// writes back byte for byte. INVALID_ARGUMENT naming what is wrong and where.
absl::StatusOr<MeshletFile> DecodeMeshletFile(const std::string& bytes);

// The bounds section alone: 48 bytes per meshlet, meshopt_Bounds' layout (also the glTF
// writer's bounds view, core/meshlets/meshlet_gltf.h).
std::string EncodeMeshletBounds(const std::vector<MeshletBounds>& bounds);

// Writes EncodeMeshletFile's bytes to `path`; UNAVAILABLE naming the path if it cannot.
absl::Status WriteMeshletFile(const std::string& path, const MeshletResult& meshlets,
                              uint32_t vertex_count, uint32_t max_vertices, uint32_t max_triangles);

}  // namespace mlclust

#endif  // MLCLUST_CORE_MESHLETS_MESHLET_FILE_H_
