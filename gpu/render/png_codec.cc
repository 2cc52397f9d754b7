#include "gpu/render/png_codec.h"

#include <png.h>

#include "absl/strings/str_cat.h"

namespace mlclust::gpu {

absl::StatusOr<std::string> EncodePng(const RgbaImage& image) {
  if (image.width == 0 || image.height == 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("png: an image of ", image.width, " x ", image.height, " pixels"));
  }
  const size_t pixels = static_cast<size_t>(image.width) * image.height;
  if (image.rgba.size() != 4 * pixels) {
    return absl::InvalidArgumentError(absl::StrCat("png: ", image.rgba.size(), " bytes for ",
                                                   image.width, " x ", image.height, " RGBA"));
  }
  // RGB: a quarter smaller than RGBA for an opaque picture.
  std::vector<uint8_t> rgb(3 * pixels);
  for (size_t i = 0; i < pixels; ++i) {
    rgb[3 * i] = image.rgba[4 * i];
    rgb[3 * i + 1] = image.rgba[4 * i + 1];
    rgb[3 * i + 2] = image.rgba[4 * i + 2];
  }
  png_image png{};
  png.version = PNG_IMAGE_VERSION;
  png.width = image.width;
  png.height = image.height;
  png.format = PNG_FORMAT_RGB;
  png_alloc_size_t bytes = 0;
  // First call: the size only; the second writes.
  if (png_image_write_to_memory(&png, nullptr, &bytes, 0, rgb.data(), 0, nullptr) == 0) {
    std::string message = png.message;
    png_image_free(&png);
    return absl::InternalError(absl::StrCat("png: libpng cannot encode: ", message));
  }
  std::string out(bytes, '\0');
  if (png_image_write_to_memory(&png, out.data(), &bytes, 0, rgb.data(), 0, nullptr) == 0) {
    std::string message = png.message;
    png_image_free(&png);
    return absl::InternalError(absl::StrCat("png: libpng cannot encode: ", message));
  }
  out.resize(bytes);
  return out;
}

absl::StatusOr<RgbaImage> DecodePng(std::string_view png_bytes, uint64_t max_pixels) {
  png_image png{};
  png.version = PNG_IMAGE_VERSION;
  if (png_image_begin_read_from_memory(&png, png_bytes.data(), png_bytes.size()) == 0) {
    std::string message = png.message;
    png_image_free(&png);
    return absl::InvalidArgumentError(absl::StrCat("png: not a PNG libpng reads: ", message));
  }
  const uint64_t pixels = uint64_t{png.width} * png.height;
  if (pixels == 0 || pixels > max_pixels) {
    png_image_free(&png);
    return absl::InvalidArgumentError(absl::StrCat("png: ", png.width, " x ", png.height,
                                                   " pixels (at most ", max_pixels, " accepted)"));
  }
  png.format = PNG_FORMAT_RGBA;
  RgbaImage image;
  image.width = png.width;
  image.height = png.height;
  image.rgba.resize(PNG_IMAGE_SIZE(png));
  if (png_image_finish_read(&png, nullptr, image.rgba.data(), 0, nullptr) == 0) {
    std::string message = png.message;
    png_image_free(&png);
    return absl::InvalidArgumentError(absl::StrCat("png: broken PNG data: ", message));
  }
  return image;
}

}  // namespace mlclust::gpu
