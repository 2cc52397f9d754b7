// The preview of a mesh job (JobSpec.preview, issue 10): which level is drawn, the size
// limits, and the drawing through the worker's GL context (gpu/render/cluster_preview.h).
#ifndef MLCLUST_SERVER_PREVIEW_H_
#define MLCLUST_SERVER_PREVIEW_H_

#include <cstdint>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/hierarchy/hierarchy.h"
#include "core/mesh/mesh.h"
#include "mlclust/v1/mlclust.pb.h"

namespace mlclust::gpu {
class GlContext;
}

namespace mlclust::server {

inline constexpr uint32_t kDefaultPreviewWidth = 1024;
inline constexpr uint32_t kDefaultPreviewHeight = 768;
// Each side of a preview, in pixels: at least a readable thumbnail, at most what keeps
// the read-back (4 bytes a pixel, 64 MiB) and the event small.
inline constexpr uint32_t kMinPreviewSide = 16;
inline constexpr uint32_t kMaxPreviewSide = 4096;

// The largest PNG a Preview event carries, so that the event stays under gRPC's default
// 4 MiB message limit (what a client that lifts no limit accepts).
inline constexpr size_t kMaxPreviewPngBytes = (size_t{4} << 20) - (size_t{64} << 10);

// "WxH" (e.g. "800x600") as two sides. INVALID_ARGUMENT naming `what` (e.g.
// "--preview-size") for anything else or a side outside [kMinPreviewSide, kMaxPreviewSide].
absl::StatusOr<std::pair<uint32_t, uint32_t>> ParsePreviewSize(absl::string_view text,
                                                               absl::string_view what);

// "AZ,EL" in degrees (e.g. "215,20") as the two angles of PreviewRequest. INVALID_ARGUMENT
// naming `what` (e.g. "--preview-view") for anything else or an elevation outside
// [-89, 89] or an azimuth outside [-360, 360].
absl::StatusOr<std::pair<float, float>> ParsePreviewView(absl::string_view text,
                                                         absl::string_view what);

// What a PreviewRequest asks for, after its defaults.
struct PreviewSettings {
  uint32_t width = kDefaultPreviewWidth;
  uint32_t height = kDefaultPreviewHeight;
  float azimuth_degrees = 35.0f;
  float elevation_degrees = 25.0f;
};

// The request's settings (0 or unset = default), or INVALID_ARGUMENT naming the field
// ("preview.width", "preview.elevation_degrees", ...) and its range.
absl::StatusOr<PreviewSettings> CheckPreviewRequest(const v1::PreviewRequest& request);

// Follows the labels through a run's levels and keeps those of the level a preview draws:
// the last level with exactly `cluster_count` clusters, else the first with fewer; with
// cluster_count 0, the last level. One label per element; O(moves) in all.
class PreviewLevelSink : public LevelSink {
 public:
  explicit PreviewLevelSink(uint32_t cluster_count) : wanted_(cluster_count) {}

  absl::Status OnStart(std::span<const ClusterId> labels, uint32_t cluster_count,
                       double energy) override;
  absl::Status OnLevel(const LevelMoves& level) override;

  std::span<const ClusterId> labels() const { return labels_; }
  uint32_t cluster_count() const { return cluster_count_; }
  uint32_t level() const { return level_; }  // the engine's level number (0: the start)

 private:
  uint32_t wanted_;
  bool frozen_ = false;  // the level is chosen; later levels are ignored
  std::vector<ClusterId> labels_;
  uint32_t cluster_count_ = 0;
  uint32_t level_ = 0;
};

// Draws the level `levels` kept and encodes it as PNG. FAILED_PRECONDITION without a GL
// context (`gl` null, or a build without MLCLUST_WITH_GPU); RESOURCE_EXHAUSTED for a PNG
// over kMaxPreviewPngBytes (the message says to ask for fewer pixels); the renderer's
// errors otherwise, prefixed with "preview".
absl::StatusOr<v1::Preview> RenderPreview(gpu::GlContext* gl, const std::string& renderer,
                                          const TriangleMesh& mesh, const FaceAdjacency& adjacency,
                                          const PreviewLevelSink& levels,
                                          const v1::PreviewRequest& request);

}  // namespace mlclust::server

#endif  // MLCLUST_SERVER_PREVIEW_H_
