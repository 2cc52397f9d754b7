// A mesh ready for the algorithms: validated, with its face adjacency and face measures,
// all owned in one value. PrepareMesh is the one set-up path (validate -> adjacency ->
// measures); core/io/prepare_mesh.h adds reading a file or decoding Draco in front of it.
#ifndef MLCLUST_CORE_MESH_PREPARED_MESH_H_
#define MLCLUST_CORE_MESH_PREPARED_MESH_H_

#include <atomic>

#include "absl/status/statusor.h"
#include "core/mesh/face_measures.h"
#include "core/mesh/mesh.h"

namespace mlclust {

struct PreparedMesh {
  TriangleMesh mesh;
  FaceAdjacency adjacency;  // BuildFaceAdjacency(mesh)
  FaceMeasures measures;    // ComputeFaceMeasures(mesh)
};

struct PrepareMeshOptions {
  // Checked between the steps and every few thousand elements of each (core/base/cancel.h).
  const std::atomic<bool>* cancel = nullptr;
};

// ValidateMesh, then adjacency and measures. Returns ValidateMesh's INVALID_ARGUMENT for
// an untrusted mesh that fails it, or CANCELLED.
absl::StatusOr<PreparedMesh> PrepareMesh(TriangleMesh mesh, const PrepareMeshOptions& options = {});

}  // namespace mlclust

#endif  // MLCLUST_CORE_MESH_PREPARED_MESH_H_
