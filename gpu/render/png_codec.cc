#include "gpu/render/png_codec.h"

#include <png.h>

#include <csetjmp>

#include "absl/strings/str_cat.h"

namespace mlclust::gpu {

namespace {

void AppendToString(png_structp png, png_bytep data, png_size_t length) {
  static_cast<std::string*>(png_get_io_ptr(png))
      ->append(reinterpret_cast<const char*>(data), length);
}

void NoFlush(png_structp /*png*/) {}

// libpng reports errors by longjmp; the message is kept for the status.
void KeepError(png_structp png, png_const_charp message) {
  *static_cast<std::string*>(png_get_error_ptr(png)) = message;
  png_longjmp(png, 1);
}

void IgnoreWarning(png_structp /*png*/, png_const_charp /*message*/) {}

// The writing itself, in a function of its own with only plain locals, because libpng's
// errors longjmp out of it.
bool WriteRgbRows(png_structp png, png_infop info, const std::vector<png_bytep>& rows,
                  uint32_t width, uint32_t height, std::string* out) {
  if (setjmp(png_jmpbuf(png))) return false;  // NOLINT(cert-err52-cpp): libpng's protocol
  png_set_write_fn(png, out, AppendToString, NoFlush);
  png_set_IHDR(png, info, width, height, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  // Previews are large flat areas: zlib's fastest level with the SUB filter encodes the
  // bunny00 preview (1024x768) in 0.022 s and 274 KB, against 0.198 s and 237 KB with
  // libpng's defaults (bench/preview_bench).
  png_set_compression_level(png, 1);
  png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_SUB);
  png_write_info(png, info);
  png_write_image(png, const_cast<png_bytepp>(rows.data()));
  png_write_end(png, nullptr);
  return true;
}

}  // namespace

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
  std::vector<png_bytep> rows(image.height);
  for (uint32_t y = 0; y < image.height; ++y)
    rows[y] = &rgb[3 * static_cast<size_t>(y) * image.width];
  std::string error;
  png_structp png =
      png_create_write_struct(PNG_LIBPNG_VER_STRING, &error, KeepError, IgnoreWarning);
  if (png == nullptr) return absl::ResourceExhaustedError("png: libpng has no memory");
  png_infop info = png_create_info_struct(png);
  if (info == nullptr) {
    png_destroy_write_struct(&png, nullptr);
    return absl::ResourceExhaustedError("png: libpng has no memory");
  }
  std::string out;
  out.reserve(pixels / 4);
  const bool written = WriteRgbRows(png, info, rows, image.width, image.height, &out);
  png_destroy_write_struct(&png, &info);
  if (!written) return absl::InternalError(absl::StrCat("png: libpng cannot encode: ", error));
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
