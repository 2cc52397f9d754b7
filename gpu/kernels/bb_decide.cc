#include "gpu/kernels/bb_decide.h"

#include <algorithm>
#include <array>

#include "absl/strings/str_cat.h"
#include "gpu/context/gl_functions.h"
#include "gpu/context/pass.h"
#include "gpu/kernels/bb_decide_glsl.h"          // kBbDecideGlsl, generated
#include "gpu/kernels/bb_scatter_labels_glsl.h"  // kBbScatterLabelsGlsl, generated

namespace mlclust::gpu {
namespace {

constexpr char kPass[] = "bb decide";
constexpr uint32_t kNoTarget = 0xFFFFFFFFu;  // boundary_based::kNoMove

static_assert(sizeof(PointAndWeight) == 32);
static_assert(sizeof(std::array<FaceId, 3>) == 12);

}  // namespace

uint64_t BoundaryDecideMemoryBound(uint64_t num_faces, uint64_t num_clusters) {
  return num_faces * (12 + 4 + 32 + 8) + BoundaryDecideMaxChanges(num_faces) * 8 +
         num_clusters * 32 + 4;
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
    const uint64_t bytes[kBindings] = {faces_or_one * 12,
                                       faces_or_one * 4,
                                       faces_or_one * 32,
                                       std::max<uint64_t>(num_clusters, 1) * 32,
                                       faces_or_one * 8,
                                       4,
                                       BoundaryDecideMaxChanges(n) * 8};
    MLCLUST_ASSIGN_OR_RETURN(std::vector<StorageBuffer> buffers,
                             CreateStorageBuffers(context, bytes));
    MLCLUST_RETURN_IF_ERROR(
        buffers[kNeighbours].Upload(std::span<const std::array<FaceId, 3>>(adjacency.neighbours)));
    MLCLUST_RETURN_IF_ERROR(buffers[kFaces].Upload(faces));
    MLCLUST_RETURN_IF_ERROR(CheckGlError(context, kPass));
    return BoundaryDecideKernel(context, static_cast<uint32_t>(n), num_clusters,
                                std::move(buffers));
  }();
  if (!kernel.ok()) return PassError(kPass, kernel.status());
  return kernel;
}

absl::Status BoundaryDecideKernel::UpdateLabels(std::span<const uint32_t> labels) {
  changes_.clear();
  const uint64_t max_changes = BoundaryDecideMaxChanges(num_faces_);
  bool all = labels_on_gpu_.size() != labels.size();
  for (uint32_t f = 0; !all && f < num_faces_; ++f) {
    if (labels[f] == labels_on_gpu_[f]) continue;
    if (changes_.size() == max_changes) {
      all = true;
      break;
    }
    changes_.push_back({f, labels[f]});
  }
  labels_on_gpu_.clear();  // unknown until the upload has worked
  if (all) {
    MLCLUST_RETURN_IF_ERROR(buffers_[kLabels].Upload(labels));
  } else if (!changes_.empty()) {
    MLCLUST_ASSIGN_OR_RETURN(
        const uint32_t scatter,
        GetComputeProgram(*context_, "bb_scatter_labels",
                          absl::StrCat(kComputeShaderPrelude, kBbScatterLabelsGlsl)));
    MLCLUST_RETURN_IF_ERROR(
        buffers_[kChanges].Upload(std::span<const std::array<uint32_t, 2>>(changes_)));
    const detail::GlFunctions& gl = context_->gl();
    gl.UseProgram(scatter);
    buffers_[kLabels].Bind(kLabels);
    buffers_[kChanges].Bind(kChanges);
    gl.ProgramUniform1ui(scatter, 0, static_cast<GLuint>(changes_.size()));
    MLCLUST_RETURN_IF_ERROR(DispatchLinear(*context_, changes_.size()));
    gl.MemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  }
  labels_on_gpu_.assign(labels.begin(), labels.end());
  return absl::OkStatus();
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
  std::fill(target.begin(), target.end(), kNoTarget);
  if (num_faces_ == 0) return absl::OkStatus();
  MLCLUST_RETURN_IF_ERROR(BeginPass(*context_, kPass));
  const absl::Status status = [&]() -> absl::Status {
    MLCLUST_RETURN_IF_ERROR(UpdateLabels(labels));
    MLCLUST_RETURN_IF_ERROR(buffers_[kProxies].Upload(proxies));
    MLCLUST_RETURN_IF_ERROR(DispatchBoundaryDecide(
        *context_, kPass,
        {&buffers_[kNeighbours], &buffers_[kLabels], &buffers_[kFaces], &buffers_[kProxies],
         &buffers_[kProposals], &buffers_[kProposalCount]},
        num_faces_, num_clusters_, proposals_));
    for (const auto& [face, cluster] : proposals_) {
      target[face] = cluster;
    }
    return absl::OkStatus();
  }();
  if (!status.ok()) {
    labels_on_gpu_.clear();
    std::fill(target.begin(), target.end(), kNoTarget);
  }
  return PassError(kPass, status);
}

absl::Status DispatchBoundaryDecide(GlContext& context, const char* pass,
                                    const BoundaryDecideBuffers& buffers, uint32_t num_faces,
                                    uint32_t num_clusters,
                                    std::vector<std::array<uint32_t, 2>>& proposals) {
  MLCLUST_ASSIGN_OR_RETURN(
      const uint32_t program,
      GetComputeProgram(context, "bb_decide", absl::StrCat(kComputeShaderPrelude, kBbDecideGlsl)));
  uint32_t count = 0;
  MLCLUST_RETURN_IF_ERROR(buffers.count->Upload(0, &count, sizeof(count)));
  const std::array<StorageBuffer*, 6> bound = {buffers.neighbours, buffers.labels,
                                               buffers.faces,      buffers.proxies,
                                               buffers.proposals,  buffers.count};
  for (uint32_t b = 0; b < bound.size(); ++b) bound[b]->Bind(b);
  const detail::GlFunctions& gl = context.gl();
  gl.UseProgram(program);
  gl.ProgramUniform1ui(program, 0, num_faces);
  MLCLUST_RETURN_IF_ERROR(DispatchLinear(context, num_faces));
  gl.UseProgram(0);
  proposals.clear();
  MLCLUST_RETURN_IF_ERROR(buffers.count->Download(0, &count, sizeof(count)));
  if (count > num_faces) {
    return absl::InternalError(
        absl::StrCat("the GPU reports ", count, " proposals for ", num_faces, " faces"));
  }
  proposals.resize(count);
  if (count > 0) {
    MLCLUST_RETURN_IF_ERROR(
        buffers.proposals->Download(std::span<std::array<uint32_t, 2>>(proposals)));
  }
  MLCLUST_RETURN_IF_ERROR(CheckGlError(context, pass));
  for (const auto& [face, cluster] : proposals) {
    if (face >= num_faces || cluster >= num_clusters) {
      return absl::InternalError(absl::StrCat("the GPU proposes face ", face, " -> cluster ",
                                              cluster, " of ", num_faces, " faces and ",
                                              num_clusters, " clusters"));
    }
  }
  return absl::OkStatus();
}

}  // namespace mlclust::gpu
