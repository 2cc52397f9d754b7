#include "gpu/kernels/ln_kmeans.h"

#include <algorithm>

#include "absl/strings/str_cat.h"
#include "core/base/status_macros.h"
#include "gpu/context/gl_functions.h"
#include "gpu/context/pass.h"
#include "gpu/kernels/ln_kmeans_assign_glsl.h"      // kLnKmeansAssignGlsl, generated
#include "gpu/kernels/ln_kmeans_neighbours_glsl.h"  // kLnKmeansNeighboursGlsl, generated

namespace mlclust::gpu {
namespace {

constexpr char kAssignPass[] = "ln-kmeans assign";
constexpr char kNeighboursPass[] = "ln-kmeans neighbours";
enum Binding : uint32_t {
  kPoints,
  kOrigin,
  kLabels,
  kCentroids,
  kNeighbours,
  kCounts,
  kCheck,
  kTargets,
  kBindings
};

}  // namespace

uint64_t LnKmeansMemoryBound(uint64_t num_points, uint32_t dims, uint32_t num_clusters) {
  return num_points * (4 * uint64_t{dims} + 12) + 8 * uint64_t{dims} +
         uint64_t{num_clusters} * (16 * uint64_t{dims} + 4);
}

absl::StatusOr<LnKmeansKernel> LnKmeansKernel::Create(GlContext& context, const PointSet& points,
                                                      std::span<const double> origin,
                                                      uint32_t num_clusters) {
  const uint32_t d = points.dims;
  const uint64_t m = points.num_points();
  if (d == 0 || d > kLnKmeansMaxDims || origin.size() != d) {
    return absl::InvalidArgumentError(absl::StrCat("ln-kmeans on the GPU: d = ", d, " (1..",
                                                   kLnKmeansMaxDims, "), origin of ",
                                                   origin.size()));
  }
  if (m >= (uint64_t{1} << 31) || m * d >= (uint64_t{1} << 32) ||
      uint64_t{num_clusters} * 2 * d >= (uint64_t{1} << 32)) {
    return absl::InvalidArgumentError(absl::StrCat("ln-kmeans on the GPU: ", m, " points of ", d,
                                                   " dimensions exceed 32-bit indices"));
  }
  MLCLUST_RETURN_IF_ERROR(BeginPass(context, kAssignPass));
  absl::StatusOr<LnKmeansKernel> kernel = [&]() -> absl::StatusOr<LnKmeansKernel> {
    const uint64_t points_or_one = std::max<uint64_t>(m, 1);
    const uint64_t k = std::max<uint32_t>(num_clusters, 1);
    const uint64_t bytes[kBindings] = {
        points_or_one * d * 4, uint64_t{d} * 8, points_or_one * 4, k * d * 8,
        k * 2 * d * 4,         k * 4,           points_or_one * 4, points_or_one * 4};
    MLCLUST_ASSIGN_OR_RETURN(std::vector<StorageBuffer> buffers,
                             CreateStorageBuffers(context, bytes));
    MLCLUST_RETURN_IF_ERROR(buffers[kPoints].Upload(std::span<const float>(points.values)));
    MLCLUST_RETURN_IF_ERROR(buffers[kOrigin].Upload(origin));
    MLCLUST_RETURN_IF_ERROR(CheckGlError(context, kAssignPass));
    return LnKmeansKernel(context, static_cast<uint32_t>(m), d, num_clusters, std::move(buffers));
  }();
  if (!kernel.ok()) return PassError(kAssignPass, kernel.status());
  return kernel;
}

absl::Status LnKmeansKernel::SetClusters(std::span<const double> centroids,
                                         std::span<const uint32_t> neighbours,
                                         std::span<const uint32_t> counts) {
  const uint64_t k = num_clusters_;
  if (centroids.size() != k * dims_ || neighbours.size() != k * 2 * dims_ || counts.size() != k) {
    return absl::InvalidArgumentError(
        absl::StrCat("ln-kmeans on the GPU: ", centroids.size(), " centroid values, ",
                     neighbours.size(), " neighbours and ", counts.size(), " counts for ", k,
                     " clusters of ", dims_, " dimensions"));
  }
  MLCLUST_RETURN_IF_ERROR(BeginPass(*context_, kAssignPass));
  absl::Status status = [&]() -> absl::Status {
    MLCLUST_RETURN_IF_ERROR(buffers_[kCentroids].Upload(centroids));
    MLCLUST_RETURN_IF_ERROR(buffers_[kNeighbours].Upload(neighbours));
    MLCLUST_RETURN_IF_ERROR(buffers_[kCounts].Upload(counts));
    return CheckGlError(*context_, kAssignPass);
  }();
  return PassError(kAssignPass, status);
}

absl::Status LnKmeansKernel::Assign(std::span<const uint32_t> labels,
                                    std::span<const uint32_t> check, std::span<uint32_t> target) {
  if (labels.size() != num_points_ || check.size() != target.size() || check.size() > num_points_) {
    return absl::InvalidArgumentError(absl::StrCat(
        "ln-kmeans on the GPU: ", labels.size(), " labels, ", check.size(), " points to check and ",
        target.size(), " targets for ", num_points_, " points"));
  }
  for (uint32_t i : check) {
    if (i >= num_points_) {
      return absl::InvalidArgumentError(
          absl::StrCat("ln-kmeans on the GPU: point ", i, " of ", num_points_));
    }
  }
  if (check.empty()) return absl::OkStatus();
  MLCLUST_RETURN_IF_ERROR(BeginPass(*context_, kAssignPass));
  absl::Status status = [&]() -> absl::Status {
    MLCLUST_ASSIGN_OR_RETURN(
        const uint32_t program,
        GetComputeProgram(*context_, "ln_kmeans_assign",
                          absl::StrCat(kComputeShaderPrelude, kLnKmeansAssignGlsl)));
    MLCLUST_RETURN_IF_ERROR(buffers_[kLabels].Upload(labels));
    MLCLUST_RETURN_IF_ERROR(buffers_[kCheck].Upload(check));
    const detail::GlFunctions& gl = context_->gl();
    gl.UseProgram(program);
    for (uint32_t b = 0; b < kBindings; ++b) buffers_[b].Bind(b);
    gl.ProgramUniform1ui(program, 0, static_cast<GLuint>(check.size()));
    gl.ProgramUniform1ui(program, 1, dims_);
    MLCLUST_RETURN_IF_ERROR(DispatchLinear(*context_, check.size()));
    gl.UseProgram(0);
    MLCLUST_RETURN_IF_ERROR(buffers_[kTargets].Download(0, target.data(), target.size_bytes()));
    return CheckGlError(*context_, kAssignPass);
  }();
  return PassError(kAssignPass, status);
}

absl::Status LnKmeansKernel::InitialNeighbours(std::span<uint32_t> neighbours) {
  if (neighbours.size() != uint64_t{num_clusters_} * 2 * dims_) {
    return absl::InvalidArgumentError(absl::StrCat("ln-kmeans on the GPU: ", neighbours.size(),
                                                   " neighbour slots for ", num_clusters_,
                                                   " clusters"));
  }
  if (num_clusters_ == 0) return absl::OkStatus();
  MLCLUST_RETURN_IF_ERROR(BeginPass(*context_, kNeighboursPass));
  absl::Status status = [&]() -> absl::Status {
    MLCLUST_ASSIGN_OR_RETURN(
        const uint32_t program,
        GetComputeProgram(*context_, "ln_kmeans_neighbours",
                          absl::StrCat(kComputeShaderPrelude, kLnKmeansNeighboursGlsl)));
    const detail::GlFunctions& gl = context_->gl();
    gl.UseProgram(program);
    for (uint32_t b = 0; b < kBindings; ++b) buffers_[b].Bind(b);
    gl.ProgramUniform1ui(program, 0, num_clusters_);
    gl.ProgramUniform1ui(program, 1, dims_);
    MLCLUST_RETURN_IF_ERROR(DispatchLinear(*context_, num_clusters_));
    gl.UseProgram(0);
    MLCLUST_RETURN_IF_ERROR(buffers_[kNeighbours].Download(std::span<uint32_t>(neighbours)));
    return CheckGlError(*context_, kNeighboursPass);
  }();
  return PassError(kNeighboursPass, status);
}

}  // namespace mlclust::gpu
