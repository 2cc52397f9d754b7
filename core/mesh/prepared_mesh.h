// A mesh ready for the algorithms: validated, with its face adjacency and face measures,
// all owned in one value. PrepareMesh is the one set-up path (validate -> adjacency ->
// measures); core/io/prepare_mesh.h adds reading a file or decoding Draco in front of it.
#ifndef MLCLUST_CORE_MESH_PREPARED_MESH_H_
#define MLCLUST_CORE_MESH_PREPARED_MESH_H_

#include <atomic>
#include <functional>

#include "absl/status/statusor.h"
#include "core/mesh/face_measures.h"
#include "core/mesh/mesh.h"

namespace mlclust {

struct PreparedMesh {
  TriangleMesh mesh;
  FaceAdjacency adjacency;  // BuildFaceAdjacency(mesh)
  FaceMeasures measures;    // ComputeFaceMeasures(mesh)
};

// The measures step on another device (the server's GPU: gpu/kernels/face_measures_gpu.h),
// called with the validated mesh and the options' cancel flag. It must give what
// ComputeFaceMeasures gives (one entry per face) or an error, which PrepareMesh returns.
using MeasureFacesFunction = std::function<absl::StatusOr<FaceMeasures>(
    const TriangleMesh& mesh, const std::atomic<bool>* cancel)>;

struct PrepareMeshOptions {
  // Checked between the steps and every few thousand elements of each (core/base/cancel.h).
  const std::atomic<bool>* cancel = nullptr;
  // Empty: ComputeFaceMeasures on the CPU.
  MeasureFacesFunction measure_faces;
};

// ValidateMesh, then adjacency and measures (options.measure_faces where set). Returns
// ValidateMesh's INVALID_ARGUMENT for an untrusted mesh that fails it, CANCELLED, the
// measures function's error, or INTERNAL where it returns measures of another size.
absl::StatusOr<PreparedMesh> PrepareMesh(TriangleMesh mesh, const PrepareMeshOptions& options = {});

}  // namespace mlclust

#endif  // MLCLUST_CORE_MESH_PREPARED_MESH_H_
