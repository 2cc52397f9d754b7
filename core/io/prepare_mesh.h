// Read or decode a mesh and prepare it for the algorithms in one call:
// read/decode -> ValidateMesh -> face adjacency -> face measures (core/mesh/prepared_mesh.h).
// The one set-up path for the server, the CLI, the benches and the tests.
#ifndef MLCLUST_CORE_IO_PREPARE_MESH_H_
#define MLCLUST_CORE_IO_PREPARE_MESH_H_

#include <string>
#include <string_view>

#include "absl/status/statusor.h"
#include "core/mesh/prepared_mesh.h"

namespace mlclust {

// ReadMeshFile (core/io/mesh_io.h: OFF, PLY, OBJ, glTF, ...), then PrepareMesh. The
// reader's error (NOT_FOUND, INVALID_ARGUMENT naming the file) or PrepareMesh's.
absl::StatusOr<PreparedMesh> PrepareMeshFile(const std::string& path,
                                             const PrepareMeshOptions& options = {});

// DecodeDracoMesh (core/io/draco_codec.h: faces in the encoder's order), then PrepareMesh.
absl::StatusOr<PreparedMesh> PrepareDracoMesh(std::string_view bytes,
                                              const PrepareMeshOptions& options = {});

}  // namespace mlclust

#endif  // MLCLUST_CORE_IO_PREPARE_MESH_H_
