#include "gpu/kernels/seed_growth.h"

#include <algorithm>
#include <array>
#include <type_traits>
#include <utility>

#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"
#include "core/base/ids.h"
#include "core/base/status_macros.h"
#include "gpu/context/compute.h"
#include "gpu/context/gl_functions.h"
#include "gpu/context/pass.h"
#include "gpu/kernels/boundary_faces.h"
#include "gpu/kernels/seed_growth_glsl.h"  // kSeedGrowthGlsl, generated

namespace mlclust::gpu {
namespace {

// The adjacency is uploaded as it lies in memory: three 32-bit face ids per face.
static_assert(sizeof(std::array<FaceId, 3>) == 12 && std::is_trivially_copyable_v<FaceId>);

constexpr uint32_t kFree = ClusterId::kInvalidValue;

// The faces' count, the adjacency's ids and the seeds' range (what memory safety needs;
// repeated seeds are the caller's check: core's CheckSeedFaces), unprefixed.
absl::Status CheckInputs(const FaceAdjacency& adjacency, std::span<const uint32_t> seeds) {
  const size_t n = adjacency.num_faces();
  if (n > kMaxElementsPerChunk) {
    return absl::InvalidArgumentError(
        absl::StrCat(n, " faces exceed the limit of ", kMaxElementsPerChunk));
  }
  MLCLUST_RETURN_IF_ERROR(CheckNeighboursInRange(adjacency));
  for (size_t i = 0; i < seeds.size(); ++i) {
    if (seeds[i] >= n) {
      return absl::InvalidArgumentError(
          absl::StrCat("seeds: seed ", i, " (face ", seeds[i], ") is out of range"));
    }
  }
  return absl::OkStatus();
}

}  // namespace

uint64_t SeedGrowthMemoryBound(uint64_t num_faces) {
  return num_faces * (3 * sizeof(uint32_t) + 2 * sizeof(uint32_t)) + sizeof(uint32_t);
}

absl::StatusOr<SeedGrowthGpuResult> GrowSeedsInRoundsGpu(GlContext& context,
                                                         const FaceAdjacency& adjacency,
                                                         std::span<const uint32_t> seeds,
                                                         const std::atomic<bool>* cancel) {
  if (absl::Status checked = CheckInputs(adjacency, seeds); !checked.ok()) {
    return PassError(kSeedGrowthPass, checked);
  }
  const uint64_t n = adjacency.num_faces();
  SeedGrowthGpuResult result;
  result.labels.assign(n, kFree);
  for (uint32_t c = 0; c < seeds.size(); ++c) result.labels[seeds[c]] = c;
  if (n == 0) return result;
  if (n * 3 * sizeof(uint32_t) > static_cast<uint64_t>(context.max_storage_buffer_bytes())) {
    return PassError(
        kSeedGrowthPass,
        absl::ResourceExhaustedError(absl::StrCat(
            "the adjacency of ", n, " faces needs ", n * 3 * sizeof(uint32_t),
            " bytes in one storage buffer; the limit is ", context.max_storage_buffer_bytes())));
  }
  MLCLUST_RETURN_IF_ERROR(BeginPass(context, kSeedGrowthPass));
  absl::Status grown = [&]() -> absl::Status {
    const std::array<uint64_t, 4> bytes = {n * 3 * sizeof(uint32_t), n * sizeof(uint32_t),
                                           n * sizeof(uint32_t), sizeof(uint32_t)};
    MLCLUST_ASSIGN_OR_RETURN(std::vector<StorageBuffer> buffers,
                             CreateStorageBuffers(context, bytes));
    StorageBuffer& neighbours = buffers[0];
    StorageBuffer* before = &buffers[1];
    StorageBuffer* after = &buffers[2];
    StorageBuffer& assigned_buffer = buffers[3];
    MLCLUST_RETURN_IF_ERROR(
        neighbours.Upload(std::span<const std::array<FaceId, 3>>(adjacency.neighbours)));
    MLCLUST_RETURN_IF_ERROR(before->Upload(std::span<const uint32_t>(result.labels)));
    // Faces in a cluster so far, counted (a repeated seed, which callers must not pass,
    // labels one face).
    uint32_t assigned = static_cast<uint32_t>(std::count_if(
        result.labels.begin(), result.labels.end(), [](uint32_t label) { return label != kFree; }));
    MLCLUST_RETURN_IF_ERROR(assigned_buffer.Upload(0, &assigned, sizeof(assigned)));
    MLCLUST_ASSIGN_OR_RETURN(
        const uint32_t program,
        GetComputeProgram(context, "seed_growth",
                          absl::StrCat(kComputeShaderPrelude, kSeedGrowthGlsl)));
    const detail::GlFunctions& gl = context.gl();
    const uint64_t per_dispatch = std::max<uint64_t>(1, MaxInvocationsPerDispatch(context));
    gl.UseProgram(program);
    neighbours.Bind(0);
    assigned_buffer.Bind(3);
    // Every face is in a cluster after at most n rounds; a round that assigns none ends it.
    for (uint64_t round = 0; round < n && assigned < n; ++round) {
      MLCLUST_RETURN_IF_ERROR(CheckCancelled(cancel, "the initial growth on the GPU"));
      before->Bind(1);
      after->Bind(2);
      for (uint64_t begin = 0; begin < n; begin += per_dispatch) {
        const uint64_t end = std::min(n, begin + per_dispatch);
        gl.ProgramUniform1ui(program, 0, static_cast<GLuint>(begin));
        gl.ProgramUniform1ui(program, 1, static_cast<GLuint>(end));
        MLCLUST_RETURN_IF_ERROR(DispatchLinear(context, end - begin));
      }
      // The next round's shader reads this round's labels and counter; the download
      // below reads the counter.
      gl.MemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_BUFFER_UPDATE_BARRIER_BIT);
      uint32_t now = 0;
      MLCLUST_RETURN_IF_ERROR(assigned_buffer.Download(0, &now, sizeof(now)));
      std::swap(before, after);  // `before` now holds this round's labels
      if (now == assigned) break;
      assigned = now;
      ++result.rounds;
    }
    gl.UseProgram(0);
    MLCLUST_RETURN_IF_ERROR(before->Download(std::span<uint32_t>(result.labels)));
    return CheckGlError(context, kSeedGrowthPass);
  }();
  if (!grown.ok()) {
    context.gl().UseProgram(0);
    if (grown.code() == absl::StatusCode::kCancelled) return grown;
    return PassError(kSeedGrowthPass, grown);
  }
  return result;
}

}  // namespace mlclust::gpu
