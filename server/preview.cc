#include "server/preview.h"

#include <type_traits>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "core/base/status_macros.h"
#ifdef MLCLUST_HAVE_GPU
#include "gpu/render/cluster_preview.h"
#include "gpu/render/png_codec.h"
#endif

namespace mlclust::server {
namespace {

absl::Status CheckSide(uint32_t side, absl::string_view what) {
  if (side < kMinPreviewSide || side > kMaxPreviewSide) {
    return absl::InvalidArgumentError(
        absl::StrCat(what, ": ", side, " pixels; give ", kMinPreviewSide, " to ", kMaxPreviewSide));
  }
  return absl::OkStatus();
}

absl::Status CheckAngles(float azimuth, float elevation, absl::string_view what) {
  if (!(azimuth >= -360.0f && azimuth <= 360.0f)) {
    return absl::InvalidArgumentError(
        absl::StrCat(what, ": azimuth ", azimuth, " degrees; give -360 to 360"));
  }
  if (!(elevation >= -89.0f && elevation <= 89.0f)) {
    return absl::InvalidArgumentError(
        absl::StrCat(what, ": elevation ", elevation, " degrees; give -89 to 89"));
  }
  return absl::OkStatus();
}

// "A<separator>B", the separator one of `separators`, as two numbers (integers or floats).
template <typename T>
bool ParseTwoNumbers(absl::string_view text, absl::string_view separators, T& first, T& second) {
  const auto parse = [](absl::string_view part, T& out) {
    if constexpr (std::is_integral_v<T>) {
      return absl::SimpleAtoi(part, &out);
    } else {
      return absl::SimpleAtof(part, &out);
    }
  };
  const size_t at = text.find_first_of(separators);
  return at != absl::string_view::npos && parse(text.substr(0, at), first) &&
         parse(text.substr(at + 1), second);
}

}  // namespace

absl::StatusOr<std::pair<uint32_t, uint32_t>> ParsePreviewSize(absl::string_view text,
                                                               absl::string_view what) {
  uint32_t width = 0, height = 0;
  if (!ParseTwoNumbers(text, "xX", width, height)) {
    return absl::InvalidArgumentError(
        absl::StrCat(what, ": '", text, "' is not WIDTHxHEIGHT in pixels (e.g. 1024x768)"));
  }
  MLCLUST_RETURN_IF_ERROR(CheckSide(width, absl::StrCat(what, " width")));
  MLCLUST_RETURN_IF_ERROR(CheckSide(height, absl::StrCat(what, " height")));
  return std::make_pair(width, height);
}

absl::StatusOr<std::pair<float, float>> ParsePreviewView(absl::string_view text,
                                                         absl::string_view what) {
  float azimuth = 0, elevation = 0;
  if (!ParseTwoNumbers(text, ",", azimuth, elevation)) {
    return absl::InvalidArgumentError(
        absl::StrCat(what, ": '", text, "' is not AZIMUTH,ELEVATION in degrees (e.g. 215,20)"));
  }
  MLCLUST_RETURN_IF_ERROR(CheckAngles(azimuth, elevation, what));
  return std::make_pair(azimuth, elevation);
}

absl::StatusOr<PreviewSettings> CheckPreviewRequest(const v1::PreviewRequest& request) {
  PreviewSettings settings;
  if (request.width() != 0) settings.width = request.width();
  if (request.height() != 0) settings.height = request.height();
  MLCLUST_RETURN_IF_ERROR(CheckSide(settings.width, "preview.width"));
  MLCLUST_RETURN_IF_ERROR(CheckSide(settings.height, "preview.height"));
  if (request.has_azimuth_degrees()) settings.azimuth_degrees = request.azimuth_degrees();
  if (request.has_elevation_degrees()) settings.elevation_degrees = request.elevation_degrees();
  MLCLUST_RETURN_IF_ERROR(
      CheckAngles(settings.azimuth_degrees, settings.elevation_degrees, "preview"));
  return settings;
}

absl::Status PreviewLevelSink::OnStart(std::span<const ClusterId> labels, uint32_t cluster_count,
                                       double /*energy*/) {
  labels_.assign(labels.begin(), labels.end());
  cluster_count_ = cluster_count;
  level_ = 0;
  frozen_ = wanted_ != 0 && cluster_count < wanted_;
  return absl::OkStatus();
}

absl::Status PreviewLevelSink::OnLevel(const LevelMoves& level) {
  if (frozen_) return absl::OkStatus();
  // Past the wanted count after a level that had it exactly: keep that one.
  if (wanted_ != 0 && level.cluster_count < wanted_ && cluster_count_ == wanted_) {
    frozen_ = true;
    return absl::OkStatus();
  }
  for (size_t i = 0; i < level.element.size(); ++i) {
    const uint32_t element = level.element[i];
    if (element >= labels_.size()) {
      return absl::InternalError(absl::StrCat("preview: level ", level.level, " moves element ",
                                              element, " of ", labels_.size()));
    }
    labels_[element] = ClusterId(level.to_cluster[i]);
  }
  cluster_count_ = level.cluster_count;
  level_ = level.level;
  if (wanted_ != 0 && level.cluster_count < wanted_) frozen_ = true;  // the first with fewer
  return absl::OkStatus();
}

absl::StatusOr<v1::Preview> RenderPreview(gpu::GlContext* gl, const std::string& renderer,
                                          const TriangleMesh& mesh, const FaceAdjacency& adjacency,
                                          const PreviewLevelSink& levels,
                                          const v1::PreviewRequest& request) {
  MLCLUST_ASSIGN_OR_RETURN(const PreviewSettings settings, CheckPreviewRequest(request));
#ifdef MLCLUST_HAVE_GPU
  if (gl == nullptr) {
    return absl::FailedPreconditionError(
        "preview: drawing needs the server's GL context, and this server has none");
  }
  gpu::ClusterPreviewOptions options;
  options.width = settings.width;
  options.height = settings.height;
  options.azimuth_degrees = settings.azimuth_degrees;
  options.elevation_degrees = settings.elevation_degrees;
  MLCLUST_ASSIGN_OR_RETURN(
      const gpu::RgbaImage image,
      gpu::RenderClusterPreview(*gl, mesh, adjacency, levels.labels(), options));
  MLCLUST_ASSIGN_OR_RETURN(std::string png, gpu::EncodePng(image));
  if (png.size() > kMaxPreviewPngBytes) {
    return absl::ResourceExhaustedError(absl::StrCat(
        "preview: the PNG of ", image.width, " x ", image.height, " pixels is ", png.size(),
        " bytes, over the ", kMaxPreviewPngBytes, " a message may carry; ask for fewer pixels"));
  }
  v1::Preview preview;
  preview.set_png(std::move(png));
  preview.set_width(image.width);
  preview.set_height(image.height);
  preview.set_cluster_count(levels.cluster_count());
  preview.set_level(levels.level());
  preview.set_device(renderer);
  return preview;
#else
  return absl::FailedPreconditionError(
      "preview: this server was built without MLCLUST_WITH_GPU (no GL context to draw with)");
#endif
}

}  // namespace mlclust::server
