// DecodeMeshletFile: the meshlet file (core/meshlets/meshlet_file.h) from bytes in memory.
// What it accepts must pass CheckMeshletLayout and encode back to the same bytes.
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/meshlets/meshlet_file.h"
#include "fuzz/fuzz_check.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace mlclust;
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  const absl::StatusOr<MeshletFile> file = DecodeMeshletFile(bytes);
  if (!file.ok()) {
    MLCLUST_FUZZ_CHECK(file.status().code() == absl::StatusCode::kInvalidArgument);
    return 0;
  }
  MLCLUST_FUZZ_CHECK(
      CheckMeshletLayout(file->meshlets, file->max_vertices, file->max_triangles).ok());
  const absl::StatusOr<std::string> again = EncodeMeshletFile(
      file->meshlets, file->vertex_count, file->max_vertices, file->max_triangles);
  MLCLUST_FUZZ_CHECK(again.ok() && *again == bytes);
  return 0;
}
