#include "gpu/face_measures_gpu.h"

#include <algorithm>
#include <span>
#include <type_traits>

#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "core/base/status_macros.h"
#include "gpu/compute.h"
#include "gpu/gl_functions.h"

namespace mlclust::gpu {
namespace {

// Centroids and normals are read back straight into std::vector<Vec3>.
static_assert(sizeof(Vec3) == 3 * sizeof(double) && std::is_trivially_copyable_v<Vec3>);

// Outputs are plain double arrays, not dvec3: std430 aligns a dvec3 array element to 32
// bytes, which would not match Vec3's 24. Every expression mirrors core/face_measures.cc
// term by term, and `precise` forbids fusing multiply-adds or reordering, so a driver with
// IEEE doubles reproduces the CPU bit for bit.
constexpr absl::string_view kFaceMeasuresShaderBody = R"glsl(
layout(std430, binding = 0) readonly buffer Positions { float positions[]; };  // 3 per vertex
layout(std430, binding = 1) readonly buffer Indices { uint indices[]; };       // 3 per chunk face
layout(std430, binding = 2) writeonly buffer Areas { double areas[]; };        // 1 per chunk face
layout(std430, binding = 3) writeonly buffer Centroids { double centroids[]; };  // 3 per chunk face
layout(std430, binding = 4) writeonly buffer Normals { double normals[]; };    // 3 per chunk face
layout(location = 0) uniform uint u_face_count;  // faces in the chunk

dvec3 Position(uint vertex) {
  return dvec3(double(positions[3u * vertex]), double(positions[3u * vertex + 1u]),
               double(positions[3u * vertex + 2u]));
}

void main() {
  uint face = LinearInvocationIndex();
  if (face >= u_face_count) return;
  dvec3 a = Position(indices[3u * face]);
  dvec3 b = Position(indices[3u * face + 1u]);
  dvec3 c = Position(indices[3u * face + 2u]);
  // "centroid" is a GLSL keyword and cross() a built-in: hence mean and product.
  precise dvec3 u = b - a;
  precise dvec3 v = c - a;
  precise dvec3 product = dvec3(u.y * v.z - u.z * v.y, u.z * v.x - u.x * v.z, u.x * v.y - u.y * v.x);
  precise double twice_area = sqrt(product.x * product.x + product.y * product.y + product.z * product.z);
  precise dvec3 mean = (a + b + c) * (1.0LF / 3.0LF);
  // Vec3 operator/ multiplies by the reciprocal; do the same.
  precise dvec3 normal = twice_area > 0.0LF ? product * (1.0LF / twice_area) : dvec3(0.0LF);
  areas[face] = 0.5LF * twice_area;
  centroids[3u * face] = mean.x;
  centroids[3u * face + 1u] = mean.y;
  centroids[3u * face + 2u] = mean.z;
  normals[3u * face] = normal.x;
  normals[3u * face + 1u] = normal.y;
  normals[3u * face + 2u] = normal.z;
}
)glsl";

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
                        absl::StrCat(kComputeShaderPrelude, kFaceMeasuresShaderBody)));
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
