#include "gpu/kernels/face_measures_gpu.h"

#include <algorithm>
#include <span>
#include <type_traits>

#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "core/base/status_macros.h"
#include "gpu/context/compute.h"
#include "gpu/context/gl_functions.h"
#include "gpu/kernels/face_measures_glsl.h"  // kFaceMeasuresGlsl, generated

namespace mlclust::gpu {
namespace {

// Centroids and normals are read back straight into std::vector<Vec3>.
static_assert(sizeof(Vec3) == 3 * sizeof(double) && std::is_trivially_copyable_v<Vec3>);

absl::Status CheckMesh(const TriangleMesh& mesh) {
  if (mesh.positions.size() % 3 != 0 || mesh.indices.size() % 3 != 0) {
    return absl::InvalidArgumentError(absl::StrCat("mesh has ", mesh.positions.size(),
                                                   " coordinates and ", mesh.indices.size(),
                                                   " indices; both must be multiples of 3"));
  }
  if (mesh.num_faces() > kMaxMeshElements || mesh.num_vertices() > kMaxMeshElements) {
    return absl::InvalidArgumentError(absl::StrCat("mesh has ", mesh.num_faces(), " faces and ",
                                                   mesh.num_vertices(), " vertices; the limit is ",
                                                   kMaxMeshElements));
  }
  // The shader would read out of bounds (undefined in GL) on a bad index.
  const size_t num_vertices = mesh.num_vertices();
  for (size_t i = 0; i < mesh.indices.size(); ++i) {
    if (mesh.indices[i] >= num_vertices) {
      return absl::InvalidArgumentError(absl::StrCat("face ", i / 3, " corner ", i % 3,
                                                     " has vertex index ", mesh.indices[i],
                                                     " but there are ", num_vertices, " vertices"));
    }
  }
  return absl::OkStatus();
}

// Faces per chunk. Buffer bounds: positions whole (12 bytes/vertex, since indices reach
// anywhere); per chunk, indices 12, areas 8, centroids 24 and normals 24 bytes per face.
uint64_t ChunkFaces(const GlContext& context, uint64_t num_faces) {
  return std::min({MaxElementsPerBuffer(context, 3 * sizeof(double)), kMaxElementsPerChunk,
                   MaxInvocationsPerDispatch(context), num_faces});
}

constexpr uint64_t kChunkBytesPerFace = 3 * sizeof(uint32_t) + 7 * sizeof(double);

}  // namespace

uint64_t ComputeFaceMeasuresGpuMemoryBound(const GlContext& context, uint64_t num_faces,
                                           uint64_t num_vertices) {
  return num_vertices * 3 * sizeof(float) + ChunkFaces(context, num_faces) * kChunkBytesPerFace;
}

absl::StatusOr<FaceMeasures> ComputeFaceMeasuresGpu(GlContext& context, const TriangleMesh& mesh) {
  MLCLUST_RETURN_IF_ERROR(CheckMesh(mesh));
  MLCLUST_RETURN_IF_ERROR(context.MakeCurrent());
  const uint64_t num_faces = mesh.num_faces();
  FaceMeasures measures;
  measures.area.resize(num_faces);
  measures.centroid.resize(num_faces);
  measures.unit_normal.resize(num_faces);
  if (num_faces == 0) return measures;

  const uint64_t position_bytes = mesh.positions.size() * sizeof(float);
  if (position_bytes > static_cast<uint64_t>(context.max_storage_buffer_bytes())) {
    return absl::ResourceExhaustedError(absl::StrCat(
        "the positions of ", mesh.num_vertices(), " vertices need ", position_bytes,
        " bytes in one storage buffer; the limit is ", context.max_storage_buffer_bytes()));
  }
  const uint64_t chunk = ChunkFaces(context, num_faces);
  if (chunk == 0) {
    return absl::ResourceExhaustedError(
        absl::StrCat("storage buffers of ", context.max_storage_buffer_bytes(),
                     " bytes cannot hold the measures of one face"));
  }

  MLCLUST_ASSIGN_OR_RETURN(
      const uint32_t program,
      GetComputeProgram(context, "face_measures",
                        absl::StrCat(kComputeShaderPrelude, kFaceMeasuresGlsl)));
  MLCLUST_ASSIGN_OR_RETURN(StorageBuffer positions_buffer,
                           StorageBuffer::Create(context, position_bytes));
  MLCLUST_ASSIGN_OR_RETURN(StorageBuffer indices_buffer,
                           StorageBuffer::Create(context, chunk * 3 * sizeof(uint32_t)));
  MLCLUST_ASSIGN_OR_RETURN(StorageBuffer areas_buffer,
                           StorageBuffer::Create(context, chunk * sizeof(double)));
  MLCLUST_ASSIGN_OR_RETURN(StorageBuffer centroids_buffer,
                           StorageBuffer::Create(context, chunk * 3 * sizeof(double)));
  MLCLUST_ASSIGN_OR_RETURN(StorageBuffer normals_buffer,
                           StorageBuffer::Create(context, chunk * 3 * sizeof(double)));
  MLCLUST_RETURN_IF_ERROR(positions_buffer.Upload(std::span<const float>(mesh.positions)));

  const detail::GlFunctions& gl = context.gl();
  gl.UseProgram(program);
  positions_buffer.Bind(0);
  indices_buffer.Bind(1);
  areas_buffer.Bind(2);
  centroids_buffer.Bind(3);
  normals_buffer.Bind(4);
  for (uint64_t begin = 0; begin < num_faces; begin += chunk) {
    const uint64_t count = std::min(chunk, num_faces - begin);
    MLCLUST_RETURN_IF_ERROR(indices_buffer.Upload(
        std::span<const uint32_t>(mesh.indices).subspan(3 * begin, 3 * count)));
    gl.ProgramUniform1ui(program, 0, static_cast<GLuint>(count));
    MLCLUST_RETURN_IF_ERROR(DispatchLinear(context, count));
    MLCLUST_RETURN_IF_ERROR(
        areas_buffer.Download(0, measures.area.data() + begin, count * sizeof(double)));
    MLCLUST_RETURN_IF_ERROR(
        centroids_buffer.Download(0, measures.centroid.data() + begin, count * 3 * sizeof(double)));
    MLCLUST_RETURN_IF_ERROR(normals_buffer.Download(0, measures.unit_normal.data() + begin,
                                                    count * 3 * sizeof(double)));
  }
  gl.UseProgram(0);
  MLCLUST_RETURN_IF_ERROR(CheckGlError(context, "face measures"));
  return measures;
}

}  // namespace mlclust::gpu
