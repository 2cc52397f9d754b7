// ReadMeshFile on a PLY file: the header guard (CheckPlyHeader in core/io/mesh_io.cc, which
// keeps Assimp 5.2's PLY reader from looping forever on a truncated or unknown header),
// then Assimp's reader on what passes, then ValidateMesh. A hang here is a header the guard
// let through; libFuzzer reports it with -timeout.
#include <cstddef>
#include <cstdint>

#include "fuzz/fuzz_mesh_file.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  mlclust::fuzz::ReadMeshFileChecked("input.ply", data, size, /*check_indices=*/false);
  return 0;
}
