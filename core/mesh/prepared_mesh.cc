#include "core/mesh/prepared_mesh.h"

#include <utility>

#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"
#include "core/base/status_macros.h"

namespace mlclust {

absl::StatusOr<PreparedMesh> PrepareMesh(TriangleMesh mesh, const PrepareMeshOptions& options) {
  PreparedMesh prepared;
  // Validation builds the adjacency on the way; it is kept rather than built twice.
  MLCLUST_ASSIGN_OR_RETURN(prepared.adjacency, ValidateMeshAndBuildAdjacency(mesh, options.cancel));
  if (options.measure_faces) {
    MLCLUST_ASSIGN_OR_RETURN(prepared.measures, options.measure_faces(mesh, options.cancel));
    if (prepared.measures.num_faces() != mesh.num_faces() ||
        prepared.measures.centroid.size() != mesh.num_faces() ||
        prepared.measures.unit_normal.size() != mesh.num_faces()) {
      return absl::InternalError(absl::StrCat(
          "face measures: ", prepared.measures.num_faces(), " areas, ",
          prepared.measures.centroid.size(), " centroids and ",
          prepared.measures.unit_normal.size(), " normals for ", mesh.num_faces(), " faces"));
    }
  } else {
    MLCLUST_ASSIGN_OR_RETURN(prepared.measures, ComputeFaceMeasures(mesh, options.cancel));
  }
  prepared.mesh = std::move(mesh);
  return prepared;
}

}  // namespace mlclust
