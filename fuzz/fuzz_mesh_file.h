// What fuzz_off and fuzz_ply share: ReadMeshFile on the fuzzer's bytes as a file, with the
// reader's promises checked.
#ifndef MLCLUST_FUZZ_FUZZ_MESH_FILE_H_
#define MLCLUST_FUZZ_FUZZ_MESH_FILE_H_

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "core/io/mesh_io.h"
#include "core/mesh/mesh.h"
#include "fuzz/fuzz_check.h"

namespace mlclust::fuzz {

// Writes `data` to a scratch file named `name` (its extension picks the reader) and reads it
// with ReadMeshFile: an error must be INVALID_ARGUMENT or RESOURCE_EXHAUSTED, a mesh must
// have faces and whole triples (and, with `check_indices`, every index in range); then
// ValidateMesh runs on it.
inline void ReadMeshFileChecked(std::string_view name, const uint8_t* data, size_t size,
                                bool check_indices) {
  const std::string path =
      WriteScratchFile(name, std::string_view(reinterpret_cast<const char*>(data), size));
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(path);
  if (!mesh.ok()) {
    MLCLUST_FUZZ_CHECK(mesh.status().code() == absl::StatusCode::kInvalidArgument ||
                       mesh.status().code() == absl::StatusCode::kResourceExhausted);
    return;
  }
  MLCLUST_FUZZ_CHECK(mesh->num_faces() > 0);
  MLCLUST_FUZZ_CHECK(mesh->positions.size() % 3 == 0 && mesh->indices.size() % 3 == 0);
  if (check_indices) MLCLUST_FUZZ_CHECK(CheckVertexIndices(*mesh).ok());
  (void)ValidateMesh(*mesh);
}

}  // namespace mlclust::fuzz

#endif  // MLCLUST_FUZZ_FUZZ_MESH_FILE_H_
