// A C ABI over core/io/draco_codec.h for the Python package (loaded with ctypes): Debian
// has no Python Draco, and a C function over our own encoder keeps the wire format the
// C++ client's, face ids included.
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string>

#include "core/io/draco_codec.h"

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

}  // extern "C"
