// A picture of a clustering: the mesh drawn with one colour per cluster through the
// server's GL context (issue 10's "preview"; ours, not the dissertation's).
//
// What the picture is, so that a person can look instead of read:
//   - a fixed three-quarter view: the camera 35 degrees to the right of +z and 25 degrees
//     above it, +y up, orthographic, fitted to the projected vertices with a small margin
//     (both angles are options, for meshes that face another way);
//   - Lambert shading per face (two-sided, a light from the upper left of the camera),
//     which scales a face's colour and so keeps its hue: shape is readable, hue says the
//     cluster;
//   - each cluster a distinct colour from a golden-ratio hue sequence, chosen greedily so
//     that neighbouring clusters differ clearly (ClusterPreviewColours);
//   - dark border lines along every edge whose two faces are in different clusters;
//   - a light grey background.
// Background and borders are grey (no saturation), so a picture's distinct hues are its
// visible clusters (the tests count them).
#ifndef MLCLUST_GPU_RENDER_CLUSTER_PREVIEW_H_
#define MLCLUST_GPU_RENDER_CLUSTER_PREVIEW_H_

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "absl/status/statusor.h"
#include "core/base/ids.h"
#include "core/mesh/mesh.h"
#include "gpu/context/gl_context.h"
#include "gpu/render/png_codec.h"

namespace mlclust::gpu {

// The background's and the border lines' colours (grey: no hue).
inline constexpr std::array<uint8_t, 3> kPreviewBackground = {242, 242, 242};
inline constexpr std::array<uint8_t, 3> kPreviewBorder = {28, 28, 28};
// The colour of faces with no cluster (ClusterId::Invalid()).
inline constexpr std::array<uint8_t, 3> kPreviewNoCluster = {150, 150, 150};

struct ClusterPreviewOptions {
  // Pixels; each in [1, the driver's GL_MAX_RENDERBUFFER_SIZE and viewport limits].
  uint32_t width = 1024;
  uint32_t height = 768;
  // Where the camera is: azimuth degrees around +y from +z towards +x (any finite value),
  // elevation degrees above the x-z plane (in [-89, 89]). It looks at the mesh, +y up.
  float azimuth_degrees = 35.0f;
  float elevation_degrees = 25.0f;
  // Dark lines along edges between clusters, this many pixels wide on each side of the
  // edge (so about twice this in all). 0 draws none.
  float border_half_width_pixels = 0.75f;
};

// Per face: its colour (red, green, blue in bits 0..23) and which of its edges are cluster
// borders (bit 24 + e for edge e, from corner e to corner (e + 1) % 3). Faces with an
// invalid label get kPreviewNoCluster and no borders.
struct ClusterPreviewColours {
  std::vector<uint32_t> face;
  uint32_t cluster_count = 0;  // distinct valid labels
  // One colour per cluster, in order of each cluster's first face.
  std::vector<std::array<uint8_t, 3>> cluster_colour;
};

// The colours of ClusterPreviewColours, O(faces). Clusters are numbered in order of their
// first face and take, one by one, the entry of a golden-ratio hue palette (hue i * 0.618
// turns, saturation >= 0.55, value >= 0.8) that is farthest (RGB distance) from the
// colours of their already coloured neighbours, among the next 8 unused entries; so
// every cluster has its own colour and neighbours differ clearly. INVALID_ARGUMENT if
// labels.size() != adjacency.num_faces().
absl::StatusOr<ClusterPreviewColours> ColourClusters(const FaceAdjacency& adjacency,
                                                     std::span<const ClusterId> labels);

// Renders `mesh` with `labels` (one per face) as described at the top of this file into an
// offscreen framebuffer of `context` and reads it back. `adjacency` is the mesh's
// (BuildFaceAdjacency). Memory on the GPU: 12 bytes per vertex, 16 bytes per face (in
// chunks of at most what one storage buffer holds) and 8 bytes per pixel.
// Errors: INVALID_ARGUMENT for a size or angle out of range or labels/adjacency not
// matching the mesh; UNAVAILABLE if the context lacks what drawing needs (storage buffers in the
// vertex stage, a GL entry point); RESOURCE_EXHAUSTED when the vertices do not fit one
// storage buffer or GL is out of memory; INTERNAL for any other GL error. Expects a valid
// mesh (ValidateMesh).
absl::StatusOr<RgbaImage> RenderClusterPreview(GlContext& context, const TriangleMesh& mesh,
                                               const FaceAdjacency& adjacency,
                                               std::span<const ClusterId> labels,
                                               const ClusterPreviewOptions& options = {});

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_RENDER_CLUSTER_PREVIEW_H_
