#include "gpu/kernels/bb_decide.h"

#include <algorithm>

#include "absl/strings/str_cat.h"
#include "gpu/context/gl_functions.h"
#include "gpu/context/pass.h"
#include "gpu/kernels/bb_decide_glsl.h"  // kBbDecideGlsl, generated

namespace mlclust::gpu {
namespace {

constexpr char kPass[] = "bb decide";

static_assert(sizeof(PointAndWeight) == 32);
static_assert(sizeof(std::array<FaceId, 3>) == 12);

}  // namespace

uint64_t BoundaryDecideMemoryBound(uint64_t num_faces, uint64_t num_clusters) {
  return num_faces * (12 + 4 + 32 + 4) + num_clusters * 32;
}

absl::StatusOr<BoundaryDecideKernel> BoundaryDecideKernel::Create(
    GlContext& context, const FaceAdjacency& adjacency, std::span<const PointAndWeight> faces,
    uint32_t num_clusters) {
  const size_t n = adjacency.num_faces();
  if (faces.size() != n) {
    return absl::InvalidArgumentError(
        absl::StrCat("bb decide: ", faces.size(), " face points for ", n, " faces"));
  }
  if (n > kMaxMeshElements) {
    return absl::InvalidArgumentError(
        absl::StrCat("bb decide: ", n, " faces exceed the limit of ", kMaxMeshElements));
  }
  // An out-of-range neighbour would be an out-of-bounds read in the shader.
  for (size_t f = 0; f < n; ++f) {
    for (const FaceId g : adjacency.neighbours[f]) {
      if (g.valid() && g.value() >= n) {
        return absl::InvalidArgumentError(
            absl::StrCat("bb decide: face ", f, " has neighbour ", g.value(), " of ", n, " faces"));
      }
    }
  }
  MLCLUST_RETURN_IF_ERROR(BeginPass(context, kPass));
  absl::StatusOr<BoundaryDecideKernel> kernel = [&]() -> absl::StatusOr<BoundaryDecideKernel> {
    const uint64_t faces_or_one = std::max<uint64_t>(n, 1);
    MLCLUST_ASSIGN_OR_RETURN(const uint32_t program,
                             GetComputeProgram(context, "bb_decide",
                                               absl::StrCat(kComputeShaderPrelude, kBbDecideGlsl)));
    MLCLUST_ASSIGN_OR_RETURN(StorageBuffer neighbours,
                             StorageBuffer::Create(context, faces_or_one * 12));
    MLCLUST_ASSIGN_OR_RETURN(StorageBuffer labels,
                             StorageBuffer::Create(context, faces_or_one * 4));
    MLCLUST_ASSIGN_OR_RETURN(StorageBuffer face_points,
                             StorageBuffer::Create(context, faces_or_one * 32));
    MLCLUST_ASSIGN_OR_RETURN(
        StorageBuffer proxies,
        StorageBuffer::Create(context, std::max<uint64_t>(num_clusters, 1) * 32));
    MLCLUST_ASSIGN_OR_RETURN(StorageBuffer targets,
                             StorageBuffer::Create(context, faces_or_one * 4));
    MLCLUST_RETURN_IF_ERROR(
        neighbours.Upload(std::span<const std::array<FaceId, 3>>(adjacency.neighbours)));
    MLCLUST_RETURN_IF_ERROR(face_points.Upload(faces));
    MLCLUST_RETURN_IF_ERROR(CheckGlError(context, kPass));
    return BoundaryDecideKernel(context, program, static_cast<uint32_t>(n), num_clusters,
                                std::move(neighbours), std::move(labels), std::move(face_points),
                                std::move(proxies), std::move(targets));
  }();
  if (!kernel.ok()) return PassError(kPass, kernel.status());
  return kernel;
}

absl::Status BoundaryDecideKernel::Decide(std::span<const uint32_t> labels,
                                          std::span<const PointAndWeight> proxies,
                                          std::span<uint32_t> target) {
  if (labels.size() != num_faces_ || target.size() != num_faces_ ||
      proxies.size() != num_clusters_) {
    return absl::InvalidArgumentError(absl::StrCat(
        "bb decide: ", labels.size(), " labels, ", target.size(), " targets and ", proxies.size(),
        " proxies for ", num_faces_, " faces and ", num_clusters_, " clusters"));
  }
  if (num_faces_ == 0) return absl::OkStatus();
  MLCLUST_RETURN_IF_ERROR(BeginPass(*context_, kPass));
  const absl::Status status = [&]() -> absl::Status {
    MLCLUST_RETURN_IF_ERROR(labels_.Upload(labels));
    MLCLUST_RETURN_IF_ERROR(proxies_.Upload(proxies));
    const detail::GlFunctions& gl = context_->gl();
    gl.UseProgram(program_);
    neighbours_.Bind(0);
    labels_.Bind(1);
    faces_.Bind(2);
    proxies_.Bind(3);
    targets_.Bind(4);
    gl.ProgramUniform1ui(program_, 0, num_faces_);
    MLCLUST_RETURN_IF_ERROR(DispatchLinear(*context_, num_faces_));
    gl.UseProgram(0);
    MLCLUST_RETURN_IF_ERROR(targets_.Download(target));
    return CheckGlError(*context_, kPass);
  }();
  return PassError(kPass, status);
}

}  // namespace mlclust::gpu
