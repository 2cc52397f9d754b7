#include "core/io/prepare_mesh.h"

#include <utility>

#include "core/base/cancel.h"
#include "core/base/status_macros.h"
#include "core/io/draco_codec.h"
#include "core/io/mesh_io.h"

namespace mlclust {

absl::StatusOr<PreparedMesh> PrepareMeshFile(const std::string& path,
                                             const PrepareMeshOptions& options) {
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "reading the mesh"));
  MLCLUST_ASSIGN_OR_RETURN(TriangleMesh mesh, ReadMeshFile(path));
  return PrepareMesh(std::move(mesh), options);
}

absl::StatusOr<PreparedMesh> PrepareDracoMesh(std::string_view bytes,
                                              const PrepareMeshOptions& options) {
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "decoding the mesh"));
  MLCLUST_ASSIGN_OR_RETURN(TriangleMesh mesh, DecodeDracoMesh(bytes));
  return PrepareMesh(std::move(mesh), options);
}

}  // namespace mlclust
