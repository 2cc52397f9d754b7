// A C ABI over core/io for the Python package (loaded with ctypes): Debian has no Python
// Draco, and C functions over our own encoder keep the wire format the C++ client's, face
// ids included; the mesh readers and clustered writers come along, so that a pipeline
// reads a file with the same face ids as the CLI.
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "client/clustered_mesh_file.h"
#include "core/io/draco_codec.h"
#include "core/io/mesh_io.h"

namespace {

// Copies `message` into the caller's buffer, always NUL-terminated.
void SetError(const std::string& message, char* error, uint64_t error_size) {
  if (error == nullptr || error_size == 0) return;
  const size_t n = std::min<size_t>(message.size(), error_size - 1);
  std::memcpy(error, message.data(), n);
  error[n] = '\0';
}

}  // namespace

extern "C" {

// Encodes a triangle mesh: `positions` holds 3 * num_vertices floats, `indices` 3 *
// num_faces vertex indices. method 0 = sequential (keeps every order), 1 = edgebreaker;
// face_ids != 0 writes the per-face id attribute (edgebreaker only). On success returns
// 0 and sets *out (free it with mlclust_draco_free) and *out_size. On failure returns
// the absl::StatusCode and writes the message into `error` (error_size bytes).
__attribute__((visibility("default"))) int mlclust_draco_encode(
    const float* positions, uint64_t num_vertices, const uint32_t* indices, uint64_t num_faces,
    int quantization_bits, int speed, int method, int face_ids, char** out, uint64_t* out_size,
    char* error, uint64_t error_size) {
  mlclust::TriangleMesh mesh;
  mesh.positions.assign(positions, positions + 3 * num_vertices);
  mesh.indices.assign(indices, indices + 3 * num_faces);
  mlclust::DracoEncodeOptions options;
  options.position_quantization_bits = quantization_bits;
  options.speed = speed;
  options.method =
      method == 1 ? mlclust::DracoMethod::kEdgebreaker : mlclust::DracoMethod::kSequential;
  options.write_face_ids = face_ids != 0;
  if (method != 0 && method != 1) {
    SetError("method must be 0 (sequential) or 1 (edgebreaker)", error, error_size);
    return static_cast<int>(absl::StatusCode::kInvalidArgument);
  }
  absl::StatusOr<std::string> bytes = mlclust::EncodeMeshToDraco(mesh, options);
  if (!bytes.ok()) {
    SetError(std::string(bytes.status().message()), error, error_size);
    return static_cast<int>(bytes.status().code());
  }
  *out = static_cast<char*>(std::malloc(bytes->size() + 1));
  if (*out == nullptr) {
    SetError("out of memory", error, error_size);
    return static_cast<int>(absl::StatusCode::kResourceExhausted);
  }
  std::memcpy(*out, bytes->data(), bytes->size());
  *out_size = bytes->size();
  return 0;
}

__attribute__((visibility("default"))) void mlclust_draco_free(char* bytes) { std::free(bytes); }

// Reads a mesh file with ReadMeshFile (its face order is every output's face id). On
// success returns 0 and sets *positions (3 * *num_vertices floats) and *indices (3 *
// *num_faces), both to be freed with mlclust_draco_free; else the status code and message.
__attribute__((visibility("default"))) int mlclust_read_mesh(const char* path, float** positions,
                                                             uint64_t* num_vertices,
                                                             uint32_t** indices,
                                                             uint64_t* num_faces, char* error,
                                                             uint64_t error_size) {
  absl::StatusOr<mlclust::TriangleMesh> mesh = mlclust::ReadMeshFile(path);
  if (!mesh.ok()) {
    SetError(std::string(mesh.status().message()), error, error_size);
    return static_cast<int>(mesh.status().code());
  }
  *positions = static_cast<float*>(std::malloc(mesh->positions.size() * sizeof(float) + 1));
  *indices = static_cast<uint32_t*>(std::malloc(mesh->indices.size() * sizeof(uint32_t) + 1));
  if (*positions == nullptr || *indices == nullptr) {
    std::free(*positions);
    std::free(*indices);
    SetError("out of memory", error, error_size);
    return static_cast<int>(absl::StatusCode::kResourceExhausted);
  }
  std::memcpy(*positions, mesh->positions.data(), mesh->positions.size() * sizeof(float));
  std::memcpy(*indices, mesh->indices.data(), mesh->indices.size() * sizeof(uint32_t));
  *num_vertices = mesh->num_vertices();
  *num_faces = mesh->num_faces();
  return 0;
}

// Writes a clustered mesh by the path's extension, as the CLI's --out: .ply (the input's
// vertices and an int `cluster` face property), .glb / .gltf (the `_CLUSTER` attribute) or
// .obj (a group per cluster). labels: one per face, -1 for none. 0 or the status code.
__attribute__((visibility("default"))) int mlclust_write_clustered(
    const char* path, const float* positions, uint64_t num_vertices, const uint32_t* indices,
    uint64_t num_faces, const int64_t* labels, char* error, uint64_t error_size) {
  mlclust::TriangleMesh mesh;
  mesh.positions.assign(positions, positions + 3 * num_vertices);
  mesh.indices.assign(indices, indices + 3 * num_faces);
  std::vector<mlclust::ClusterId> ids(num_faces);
  for (uint64_t f = 0; f < num_faces; ++f) {
    if (labels[f] < -1 || labels[f] > int64_t{0xFFFFFFFE}) {
      SetError("face " + std::to_string(f) + ": label " + std::to_string(labels[f]) +
                   " is not a cluster id (or -1)",
               error, error_size);
      return static_cast<int>(absl::StatusCode::kInvalidArgument);
    }
    if (labels[f] >= 0) ids[f] = mlclust::ClusterId(static_cast<uint32_t>(labels[f]));
  }
  // The CLI's writer by extension (.ply, .glb, .gltf, .obj): client/clustered_mesh_file.h.
  const absl::Status status = mlclust::client::WriteClusteredMesh(path, mesh, ids);
  if (!status.ok()) {
    SetError(std::string(status.message()), error, error_size);
    return static_cast<int>(status.code());
  }
  return 0;
}

}  // extern "C"
