// ReadMeshFile on an OFF file: our own strict parser (OFF, COFF, NOFF, 4OFF, nOFF and the
// rest of the keyword family), polygon triangulation and the assembler, then ValidateMesh.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "core/io/mesh_io.h"
#include "core/mesh/mesh.h"
#include "fuzz/fuzz_check.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace mlclust;
  const std::string path = fuzz::WriteScratchFile(
      "input.off", std::string_view(reinterpret_cast<const char*>(data), size));
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(path);
  if (!mesh.ok()) {
    MLCLUST_FUZZ_CHECK(mesh.status().code() == absl::StatusCode::kInvalidArgument ||
                       mesh.status().code() == absl::StatusCode::kResourceExhausted);
    return 0;
  }
  MLCLUST_FUZZ_CHECK(mesh->num_faces() > 0);
  MLCLUST_FUZZ_CHECK(mesh->positions.size() % 3 == 0 && mesh->indices.size() % 3 == 0);
  MLCLUST_FUZZ_CHECK(CheckVertexIndices(*mesh).ok());
  (void)ValidateMesh(*mesh);
  return 0;
}
