#include "gpu/kernels/boundary_faces.h"

#include <algorithm>
#include <cassert>
#include <type_traits>

#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "core/base/status_macros.h"
#include "gpu/context/compute.h"
#include "gpu/context/gl_functions.h"
#include "gpu/kernels/boundary_faces_glsl.h"  // kBoundaryFacesGlsl, generated

namespace mlclust::gpu {
namespace {

// Adjacency and labels are uploaded as they lie in memory: three 32-bit face ids per face,
// one 32-bit label per face.
static_assert(sizeof(FaceId) == 4 && std::is_trivially_copyable_v<FaceId>);
static_assert(sizeof(ClusterId) == 4 && std::is_trivially_copyable_v<ClusterId>);
static_assert(sizeof(std::array<FaceId, 3>) == 12);

constexpr uint32_t kFacesPerWord = 4;

absl::Status CheckInputs(const FaceAdjacency& adjacency, std::span<const ClusterId> labels) {
  const size_t num_faces = adjacency.num_faces();
  if (labels.size() != num_faces) {
    return absl::InvalidArgumentError(absl::StrCat(
        "labels has ", labels.size(), " entries but the adjacency has ", num_faces, " faces"));
  }
  if (num_faces > kMaxMeshElements) {
    return absl::InvalidArgumentError(
        absl::StrCat(num_faces, " faces exceed the limit of ", kMaxMeshElements));
  }
  return CheckNeighboursInRange(adjacency);
}

// Faces per chunk. Buffer bounds: labels whole (4 bytes/face); per chunk, neighbours 12
// bytes/face (the largest) and flags 1 byte/face rounded up to a whole word.
uint64_t ChunkFaces(const GlContext& context, uint64_t num_faces) {
  return std::min({MaxElementsPerBuffer(context, 3 * sizeof(uint32_t)), kMaxElementsPerChunk,
                   kFacesPerWord * MaxInvocationsPerDispatch(context), num_faces});
}

uint64_t FlagBytes(uint64_t faces) {
  return (faces + kFacesPerWord - 1) / kFacesPerWord * sizeof(uint32_t);
}

}  // namespace

absl::Status CheckNeighboursInRange(const FaceAdjacency& adjacency) {
  // A neighbour id out of range would be an out-of-bounds read in the shader, which GL
  // leaves undefined (robust buffer access is not guaranteed), so check it here.
  const size_t num_faces = adjacency.num_faces();
  for (size_t face = 0; face < num_faces; ++face) {
    for (int edge = 0; edge < 3; ++edge) {
      const FaceId neighbour = adjacency.neighbours[face][edge];
      if (neighbour.valid() && neighbour.value() >= num_faces) {
        return absl::InvalidArgumentError(absl::StrCat("face ", face, " edge ", edge,
                                                       " has neighbour ", neighbour.value(),
                                                       " but there are ", num_faces, " faces"));
      }
    }
  }
  return absl::OkStatus();
}

uint64_t FlagBoundaryFacesMemoryBound(const GlContext& context, uint64_t num_faces) {
  const uint64_t chunk = ChunkFaces(context, num_faces);
  return num_faces * sizeof(uint32_t) + chunk * 3 * sizeof(uint32_t) + FlagBytes(chunk);
}

std::vector<uint8_t> FlagBoundaryFacesCpu(const FaceAdjacency& adjacency,
                                          std::span<const ClusterId> labels) {
  assert(labels.size() == adjacency.num_faces());
  std::vector<uint8_t> flags(adjacency.num_faces(), 0);
  for (size_t face = 0; face < flags.size(); ++face) {
    for (const FaceId neighbour : adjacency.neighbours[face]) {
      if (!neighbour.valid()) continue;
      assert(neighbour.value() < flags.size());
      if (labels[neighbour.value()] != labels[face]) {
        flags[face] = 1;
        break;
      }
    }
  }
  return flags;
}

absl::StatusOr<std::vector<uint8_t>> FlagBoundaryFaces(GlContext& context,
                                                       const FaceAdjacency& adjacency,
                                                       std::span<const ClusterId> labels) {
  MLCLUST_RETURN_IF_ERROR(CheckInputs(adjacency, labels));
  MLCLUST_RETURN_IF_ERROR(context.MakeCurrent());
  const uint64_t num_faces = adjacency.num_faces();
  std::vector<uint8_t> flags(num_faces, 0);
  if (num_faces == 0) return flags;

  const uint64_t chunk = ChunkFaces(context, num_faces);
  if (chunk == 0) {
    return absl::ResourceExhaustedError(absl::StrCat("storage buffers of ",
                                                     context.max_storage_buffer_bytes(),
                                                     " bytes cannot hold one chunk of adjacency"));
  }
  if (num_faces * sizeof(uint32_t) > static_cast<uint64_t>(context.max_storage_buffer_bytes())) {
    return absl::ResourceExhaustedError(absl::StrCat(
        "the labels of ", num_faces, " faces need ", num_faces * sizeof(uint32_t),
        " bytes in one storage buffer; the limit is ", context.max_storage_buffer_bytes()));
  }

  MLCLUST_ASSIGN_OR_RETURN(
      const uint32_t program,
      GetComputeProgram(context, "flag_boundary_faces",
                        absl::StrCat(kComputeShaderPrelude, kBoundaryFacesGlsl)));
  MLCLUST_ASSIGN_OR_RETURN(StorageBuffer labels_buffer,
                           StorageBuffer::Create(context, num_faces * sizeof(uint32_t)));
  MLCLUST_ASSIGN_OR_RETURN(StorageBuffer neighbours_buffer,
                           StorageBuffer::Create(context, chunk * 3 * sizeof(uint32_t)));
  MLCLUST_ASSIGN_OR_RETURN(StorageBuffer flags_buffer,
                           StorageBuffer::Create(context, FlagBytes(chunk)));
  MLCLUST_RETURN_IF_ERROR(labels_buffer.Upload(labels));

  const detail::GlFunctions& gl = context.gl();
  gl.UseProgram(program);
  labels_buffer.Bind(0);
  neighbours_buffer.Bind(1);
  flags_buffer.Bind(2);
  for (uint64_t begin = 0; begin < num_faces; begin += chunk) {
    const uint64_t count = std::min(chunk, num_faces - begin);
    MLCLUST_RETURN_IF_ERROR(neighbours_buffer.Upload(
        std::span<const std::array<FaceId, 3>>(adjacency.neighbours).subspan(begin, count)));
    gl.ProgramUniform1ui(program, 0, static_cast<GLuint>(begin));
    gl.ProgramUniform1ui(program, 1, static_cast<GLuint>(count));
    MLCLUST_RETURN_IF_ERROR(DispatchLinear(context, (count + kFacesPerWord - 1) / kFacesPerWord));
    MLCLUST_RETURN_IF_ERROR(flags_buffer.Download(0, flags.data() + begin, count));
  }
  gl.UseProgram(0);
  MLCLUST_RETURN_IF_ERROR(CheckGlError(context, "flag boundary faces"));
  return flags;
}

}  // namespace mlclust::gpu
