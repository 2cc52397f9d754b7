#include "core/mesh/prepared_mesh.h"

#include <utility>

#include "core/base/cancel.h"
#include "core/base/status_macros.h"

namespace mlclust {

absl::StatusOr<PreparedMesh> PrepareMesh(TriangleMesh mesh, const PrepareMeshOptions& options) {
  PreparedMesh prepared;
  // Validation builds the adjacency on the way; it is kept rather than built twice.
  MLCLUST_ASSIGN_OR_RETURN(prepared.adjacency, ValidateMeshAndBuildAdjacency(mesh, options.cancel));
  MLCLUST_ASSIGN_OR_RETURN(prepared.measures, ComputeFaceMeasures(mesh, options.cancel));
  prepared.mesh = std::move(mesh);
  return prepared;
}

}  // namespace mlclust
