// Draco-compressed glTF (KHR_draco_mesh_compression), made readable for Assimp, whose
// Debian build has no Draco: the compressed primitives are decoded with the Draco library
// we link and the file is rewritten as a plain GLB in memory.
#ifndef MLCLUST_CORE_IO_GLTF_DRACO_H_
#define MLCLUST_CORE_IO_GLTF_DRACO_H_

#include <functional>
#include <string>
#include <string_view>

#include "absl/status/statusor.h"

namespace mlclust {

// Whether `file` (a whole .gltf or .glb) names KHR_draco_mesh_compression in its JSON.
bool GltfUsesDraco(std::string_view file);

// Reads the buffer a glTF file names by a relative URI (the file beside it).
using GltfUriReader = std::function<absl::StatusOr<std::string>(const std::string& uri)>;

// Rewrites a glTF 2.0 file (`file`: its bytes; `read_uri`: reads the files its relative
// URIs name) as one GLB with a single embedded buffer: every buffer (the GLB's own, data:
// URIs, files) copied into it, and each primitive with KHR_draco_mesh_compression
// replaced by a plain one: POSITION as float32 VEC3 and the indices as uint32, one vertex
// per Draco point and the faces in the order the Draco data holds them (as the
// extension's spec says a decoder must). The primitive's other attributes are dropped
// (only positions are read); the node tree, transforms and plain primitives stay as they
// are. INVALID_ARGUMENT, naming the mesh and primitive or the buffer, for bad JSON, a
// buffer that cannot be read or is short, Draco data that does not decode, or counts
// that disagree with the accessors. Never crashes on corrupted or truncated bytes.
absl::StatusOr<std::string> DecompressDracoGltf(std::string_view file,
                                                const GltfUriReader& read_uri);

// A GLB (glTF 2.0, 4.4) of `json` and `bin`, each padded to 4 bytes (spaces, zeros).
// INVALID_ARGUMENT if the whole is over GLB's 4 GiB.
absl::StatusOr<std::string> PackGlb(std::string json, std::string bin);

}  // namespace mlclust

#endif  // MLCLUST_CORE_IO_GLTF_DRACO_H_
