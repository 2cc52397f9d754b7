// The Draco glTF rewriter (core/io/gltf_draco.h) on a whole .gltf or .glb: GltfUsesDraco,
// then DecompressDracoGltf with a URI reader that knows one external buffer,
// "buffer.bin" (its bytes: the input's last 256 bytes, so the fuzzer controls them too);
// every other URI is NOT_FOUND. A result must be a GLB whose header length is its size.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>

#include "core/io/gltf_draco.h"
#include "fuzz/fuzz_check.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace mlclust;
  const std::string_view file(reinterpret_cast<const char*>(data), size);
  (void)GltfUsesDraco(file);
  const std::string buffer(file.substr(file.size() > 256 ? file.size() - 256 : 0));
  absl::StatusOr<std::string> glb =
      DecompressDracoGltf(file, [&](const std::string& uri) -> absl::StatusOr<std::string> {
        if (uri == "buffer.bin") return buffer;
        return absl::NotFoundError(uri);
      });
  if (!glb.ok()) {
    MLCLUST_FUZZ_CHECK(glb.status().code() == absl::StatusCode::kInvalidArgument);
    return 0;
  }
  MLCLUST_FUZZ_CHECK(glb->size() >= 12 && glb->compare(0, 4, "glTF") == 0);
  uint32_t length = 0;
  std::memcpy(&length, glb->data() + 8, 4);
  MLCLUST_FUZZ_CHECK(length == glb->size());
  return 0;
}
