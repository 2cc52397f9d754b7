#include "gpu/kernels/kmeans_assign.h"

#include <algorithm>

#include "absl/strings/str_cat.h"
#include "core/base/status_macros.h"
#include "gpu/context/gl_functions.h"
#include "gpu/context/pass.h"
#include "gpu/kernels/kmeans_assign_glsl.h"  // kKmeansAssignGlsl, generated

namespace mlclust::gpu {
namespace {
constexpr char kPass[] = "kmeans assign";
}  // namespace

uint64_t KmeansAssignMemoryBound(uint64_t num_points, uint32_t dims, uint32_t num_centres) {
  return num_points * (4 * uint64_t{dims} + 4) + uint64_t{num_centres} * dims * 4;
}

absl::StatusOr<KmeansAssignKernel> KmeansAssignKernel::Create(GlContext& context,
                                                              const PointSet& points,
                                                              uint32_t num_centres) {
  const uint32_t d = points.dims;
  const uint64_t m = points.num_points();
  if (d == 0 || num_centres == 0 || m * d >= (uint64_t{1} << 32) ||
      uint64_t{num_centres} * d >= (uint64_t{1} << 32)) {
    return absl::InvalidArgumentError(absl::StrCat("kmeans on the GPU: ", m, " points of ", d,
                                                   " dimensions and ", num_centres, " centres"));
  }
  MLCLUST_RETURN_IF_ERROR(BeginPass(context, kPass));
  absl::StatusOr<KmeansAssignKernel> kernel = [&]() -> absl::StatusOr<KmeansAssignKernel> {
    const uint64_t points_or_one = std::max<uint64_t>(m, 1);
    MLCLUST_ASSIGN_OR_RETURN(StorageBuffer point_buffer,
                             StorageBuffer::Create(context, points_or_one * d * 4));
    MLCLUST_ASSIGN_OR_RETURN(StorageBuffer centres,
                             StorageBuffer::Create(context, uint64_t{num_centres} * d * 4));
    MLCLUST_ASSIGN_OR_RETURN(StorageBuffer labels,
                             StorageBuffer::Create(context, points_or_one * 4));
    MLCLUST_RETURN_IF_ERROR(point_buffer.Upload(std::span<const float>(points.values)));
    MLCLUST_RETURN_IF_ERROR(CheckGlError(context, kPass));
    return KmeansAssignKernel(context, static_cast<uint32_t>(m), d, num_centres,
                              std::move(point_buffer), std::move(centres), std::move(labels));
  }();
  if (!kernel.ok()) return PassError(kPass, kernel.status());
  return kernel;
}

absl::Status KmeansAssignKernel::Assign(std::span<const float> centres,
                                        std::span<uint32_t> labels) {
  if (centres.size() != uint64_t{num_centres_} * dims_ || labels.size() != num_points_) {
    return absl::InvalidArgumentError(
        absl::StrCat("kmeans on the GPU: ", centres.size(), " centre values and ", labels.size(),
                     " labels for ", num_centres_, " centres and ", num_points_, " points"));
  }
  if (num_points_ == 0) return absl::OkStatus();
  MLCLUST_RETURN_IF_ERROR(BeginPass(*context_, kPass));
  absl::Status status = [&]() -> absl::Status {
    MLCLUST_ASSIGN_OR_RETURN(
        const uint32_t program,
        GetComputeProgram(*context_, "kmeans_assign",
                          absl::StrCat(kComputeShaderPrelude, kKmeansAssignGlsl)));
    MLCLUST_RETURN_IF_ERROR(centres_.Upload(centres));
    const detail::GlFunctions& gl = context_->gl();
    gl.UseProgram(program);
    points_.Bind(0);
    centres_.Bind(1);
    labels_.Bind(2);
    gl.ProgramUniform1ui(program, 0, num_points_);
    gl.ProgramUniform1ui(program, 1, dims_);
    gl.ProgramUniform1ui(program, 2, num_centres_);
    MLCLUST_RETURN_IF_ERROR(DispatchLinear(*context_, num_points_));
    gl.UseProgram(0);
    MLCLUST_RETURN_IF_ERROR(labels_.Download(labels));
    return CheckGlError(*context_, kPass);
  }();
  return PassError(kPass, status);
}

}  // namespace mlclust::gpu
