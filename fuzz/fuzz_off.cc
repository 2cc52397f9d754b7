// ReadMeshFile on an OFF file: our own strict parser (OFF, COFF, NOFF, 4OFF, nOFF and the
// rest of the keyword family), polygon triangulation and the assembler, then ValidateMesh.
#include <cstddef>
#include <cstdint>

#include "fuzz/fuzz_mesh_file.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  mlclust::fuzz::ReadMeshFileChecked("input.off", data, size, /*check_indices=*/true);
  return 0;
}
