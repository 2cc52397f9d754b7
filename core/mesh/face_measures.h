// Per-face measures: the additive quantities every mesh energy is built from.
#ifndef MLCLUST_CORE_MESH_FACE_MEASURES_H_
#define MLCLUST_CORE_MESH_FACE_MEASURES_H_

#include <atomic>
#include <vector>

#include "absl/status/statusor.h"
#include "core/base/vec3.h"
#include "core/mesh/mesh.h"

namespace mlclust {

struct FaceMeasures {
  std::vector<double> area;       // triangle area A_j
  std::vector<Vec3> centroid;     // triangle centroid g_j (mean of its three corners)
  std::vector<Vec3> unit_normal;  // n_j, counter-clockwise orientation; zero if A_j == 0

  size_t num_faces() const { return area.size(); }
};

// Computes area, centroid and unit normal of every face, in double precision.
// Expects a mesh that passed ValidateMesh.
FaceMeasures ComputeFaceMeasures(const TriangleMesh& mesh);

// The same, CANCELLED if `cancel` (core/base/cancel.h) is set, checked every few
// thousand faces.
absl::StatusOr<FaceMeasures> ComputeFaceMeasures(const TriangleMesh& mesh,
                                                 const std::atomic<bool>* cancel);

}  // namespace mlclust

#endif  // MLCLUST_CORE_MESH_FACE_MEASURES_H_
