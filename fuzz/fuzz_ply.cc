// ReadMeshFile on a PLY file: the header guard (CheckPlyHeader in core/io/mesh_io.cc, which
// keeps Assimp 5.2's PLY reader from looping forever on a truncated or unknown header),
// then Assimp's reader on what passes, then ValidateMesh. A hang here is a header the guard
// let through; libFuzzer reports it with -timeout.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "core/io/mesh_io.h"
#include "core/mesh/mesh.h"
#include "fuzz/fuzz_check.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace mlclust;
  const std::string path = fuzz::WriteScratchFile(
      "input.ply", std::string_view(reinterpret_cast<const char*>(data), size));
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(path);
  if (!mesh.ok()) {
    MLCLUST_FUZZ_CHECK(mesh.status().code() == absl::StatusCode::kInvalidArgument ||
                       mesh.status().code() == absl::StatusCode::kResourceExhausted);
    return 0;
  }
  MLCLUST_FUZZ_CHECK(mesh->num_faces() > 0);
  MLCLUST_FUZZ_CHECK(mesh->positions.size() % 3 == 0 && mesh->indices.size() % 3 == 0);
  (void)ValidateMesh(*mesh);
  return 0;
}
