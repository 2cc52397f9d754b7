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
  kMargins,
  kBindings
};

}  // namespace

uint64_t LnKmeansMemoryBound(uint64_t num_points, uint32_t dims, uint32_t num_clusters) {
  return num_points * (4 * uint64_t{dims} + 20) + 8 * uint64_t{dims} +
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
        k * 2 * d * 4,         k * 4,           points_or_one * 4, points_or_one * 4,
        points_or_one * 8};
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
  if (labels.size() != num_points_) {
    return absl::InvalidArgumentError(absl::StrCat("ln-kmeans on the GPU: ", labels.size(),
                                                   " labels for ", num_points_, " points"));
  }
  if (check.empty()) return absl::OkStatus();
  MLCLUST_RETURN_IF_ERROR(BeginPass(*context_, kAssignPass));
  MLCLUST_RETURN_IF_ERROR(PassError(kAssignPass, buffers_[kLabels].Upload(labels)));
  return DispatchAssign(
      {&buffers_[kLabels], &buffers_[kCentroids], &buffers_[kNeighbours], &buffers_[kCounts]},
      check, target, {}, {});
}

absl::Status LnKmeansKernel::AssignResident(const LnKmeansResidentClusters& clusters,
                                            std::span<const uint32_t> check,
                                            std::span<uint32_t> target, std::span<double> margin,
                                            const LnKmeansOwnCandidates& own) {
  if (clusters.labels == nullptr || clusters.centroids == nullptr ||
      clusters.neighbours == nullptr || clusters.counts == nullptr ||
      clusters.labels->bytes() < uint64_t{num_points_} * 4) {
    return absl::InvalidArgumentError(absl::StrCat(
        "ln-kmeans on the GPU: resident clusters without labels for ", num_points_, " points"));
  }
  if (check.empty()) return absl::OkStatus();
  MLCLUST_RETURN_IF_ERROR(BeginPass(*context_, kAssignPass));
  return DispatchAssign(clusters, check, target, margin, own);
}

absl::Status LnKmeansKernel::DispatchAssign(const LnKmeansResidentClusters& clusters,
                                            std::span<const uint32_t> check,
                                            std::span<uint32_t> target, std::span<double> margin,
                                            const LnKmeansOwnCandidates& own) {
  const size_t full = own.ranges.empty() ? check.size() : own.full;
  if (check.size() != target.size() || check.size() > num_points_ ||
      (!margin.empty() && margin.size() != check.size()) || full > check.size() ||
      own.ranges.size() != 2 * (check.size() - full)) {
    return absl::InvalidArgumentError(absl::StrCat("ln-kmeans on the GPU: ", check.size(),
                                                   " points to check and ", target.size(),
                                                   " targets for ", num_points_, " points"));
  }
  for (uint32_t i : check) {
    if (i >= num_points_) {
      return absl::InvalidArgumentError(
          absl::StrCat("ln-kmeans on the GPU: point ", i, " of ", num_points_));
    }
  }
  for (size_t e = 0; e < own.ranges.size(); e += 2) {
    if (own.ranges[e] > own.ranges[e + 1] || own.ranges[e + 1] > own.candidates.size()) {
      return absl::InvalidArgumentError("ln-kmeans on the GPU: a candidate range out of range");
    }
  }
  for (uint32_t c : own.candidates) {
    if (c >= clusters.counts->bytes() / 4) {
      return absl::InvalidArgumentError(
          absl::StrCat("ln-kmeans on the GPU: candidate cluster ", c, " out of range"));
    }
  }
  absl::Status status = [&]() -> absl::Status {
    MLCLUST_ASSIGN_OR_RETURN(
        const uint32_t program,
        GetComputeProgram(*context_, "ln_kmeans_assign",
                          absl::StrCat(kComputeShaderPrelude, kLnKmeansAssignGlsl)));
    const uint64_t entries = check.size() + own.ranges.size() + own.candidates.size();
    if (entries * 4 > buffers_[kCheck].bytes()) {
      MLCLUST_ASSIGN_OR_RETURN(
          buffers_[kCheck],
          StorageBuffer::Create(*context_, std::max(entries * 4, 2 * buffers_[kCheck].bytes())));
    }
    MLCLUST_RETURN_IF_ERROR(buffers_[kCheck].Upload(check));
    if (!own.ranges.empty()) {
      MLCLUST_RETURN_IF_ERROR(buffers_[kCheck].Upload(own.ranges, check.size_bytes()));
      if (!own.candidates.empty()) {
        MLCLUST_RETURN_IF_ERROR(
            buffers_[kCheck].Upload(own.candidates, check.size_bytes() + own.ranges.size_bytes()));
      }
    }
    const detail::GlFunctions& gl = context_->gl();
    gl.UseProgram(program);
    for (uint32_t b = 0; b < kBindings; ++b) buffers_[b].Bind(b);
    clusters.labels->Bind(kLabels);
    clusters.centroids->Bind(kCentroids);
    clusters.neighbours->Bind(kNeighbours);
    clusters.counts->Bind(kCounts);
    gl.ProgramUniform1ui(program, 0, static_cast<GLuint>(check.size()));
    gl.ProgramUniform1ui(program, 1, dims_);
    gl.ProgramUniform1ui(program, 2, margin.empty() ? 0u : 1u);
    gl.ProgramUniform1ui(program, 3, static_cast<GLuint>(full));
    MLCLUST_RETURN_IF_ERROR(DispatchLinear(*context_, check.size()));
    gl.UseProgram(0);
    MLCLUST_RETURN_IF_ERROR(buffers_[kTargets].Download(0, target.data(), target.size_bytes()));
    if (!margin.empty()) {
      MLCLUST_RETURN_IF_ERROR(buffers_[kMargins].Download(0, margin.data(), margin.size_bytes()));
    }
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
