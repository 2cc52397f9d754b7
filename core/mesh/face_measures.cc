#include "core/mesh/face_measures.h"

#include "core/base/cancel.h"
#include "core/base/status_macros.h"

namespace mlclust {

absl::StatusOr<FaceMeasures> ComputeFaceMeasures(const TriangleMesh& mesh,
                                                 const std::atomic<bool>* cancel) {
  constexpr size_t kFacesPerCancelCheck = 65536;
  const size_t n = mesh.num_faces();
  FaceMeasures measures;
  measures.area.resize(n);
  measures.centroid.resize(n);
  measures.unit_normal.resize(n);
  for (size_t i = 0; i < n; ++i) {
    if (i % kFacesPerCancelCheck == 0) {
      MLCLUST_RETURN_IF_ERROR(CheckCancelled(cancel, "face measures"));
    }
    const FaceId face(static_cast<uint32_t>(i));
    const Vec3 a = mesh.position(mesh.corner(face, 0));
    const Vec3 b = mesh.position(mesh.corner(face, 1));
    const Vec3 c = mesh.position(mesh.corner(face, 2));
    const Vec3 cross = Cross(b - a, c - a);
    const double twice_area = Norm(cross);
    measures.area[i] = 0.5 * twice_area;
    measures.centroid[i] = (a + b + c) * (1.0 / 3.0);
    measures.unit_normal[i] = twice_area > 0 ? cross / twice_area : Vec3{};
  }
  return measures;
}

FaceMeasures ComputeFaceMeasures(const TriangleMesh& mesh) {
  return *ComputeFaceMeasures(mesh, nullptr);
}

}  // namespace mlclust
