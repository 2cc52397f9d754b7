// PNG files in memory, through libpng (Debian's libpng-dev): written with its classic API
// (for the compression level), read with its simplified one.
//
// No GL here: the preview renderer (cluster_preview.h) encodes with it, and tests decode
// its output with it. Pixels are 8-bit RGBA, rows top to bottom, no padding.
#ifndef MLCLUST_GPU_RENDER_PNG_CODEC_H_
#define MLCLUST_GPU_RENDER_PNG_CODEC_H_

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"

namespace mlclust::gpu {

struct RgbaImage {
  uint32_t width = 0;
  uint32_t height = 0;
  std::vector<uint8_t> rgba;  // 4 * width * height bytes, row 0 is the top row

  const uint8_t* pixel(uint32_t x, uint32_t y) const {
    return &rgba[4 * (static_cast<size_t>(y) * width + x)];
  }
};

// Encodes `image` as an 8-bit RGB PNG (alpha dropped: the previews are opaque).
// INVALID_ARGUMENT if the size is zero or rgba.size() != 4 * width * height; INTERNAL
// with libpng's message if it fails.
absl::StatusOr<std::string> EncodePng(const RgbaImage& image);

// Decodes any PNG libpng reads (any bit depth and colour type) to 8-bit RGBA. Untrusted
// input: INVALID_ARGUMENT with libpng's message for a broken file, and for images with
// more than `max_pixels` pixels (checked from the header, before any pixel is allocated).
absl::StatusOr<RgbaImage> DecodePng(std::string_view png, uint64_t max_pixels = uint64_t{1} << 26);

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_RENDER_PNG_CODEC_H_
