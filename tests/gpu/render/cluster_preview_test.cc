#include "gpu/render/cluster_preview.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>
#include <set>
#include <vector>

#include "core/mesh/mesh.h"
#include "gpu/context/gl_context.h"
#include "gpu/render/png_codec.h"
#include "tests/fixtures/gl_test_context.h"
#include "tests/fixtures/image_hues.h"
#include "tests/fixtures/test_meshes.h"

namespace mlclust::gpu {
namespace {

using ::mlclust::testing::DistinctHues;
using ::mlclust::testing::Grid;
using ::mlclust::testing::HueDistance;
using ::mlclust::testing::HueGroup;
using ::mlclust::testing::MakeCube;
using ::mlclust::testing::ToHsv;
using ::testing::HasSubstr;

std::unique_ptr<GlContext> MakeContext(const GlContextOptions& options = {}) {
  return ::mlclust::testing::MakeGlContext(options);
}

using ::mlclust::testing::AdjacencyOf;

// A GL context whose storage buffers hold at most `bytes`.
std::unique_ptr<GlContext> ContextWithBuffersOf(int64_t bytes) {
  GlContextOptions options;
  options.max_storage_buffer_bytes = bytes;
  return MakeContext(options);
}

// Default options at width x height pixels.
ClusterPreviewOptions Sized(uint32_t width, uint32_t height) {
  ClusterPreviewOptions options;
  options.width = width;
  options.height = height;
  return options;
}

// Grid(n) (z = 0, two triangles per square, square (x, y) has faces 2 (y n + x) and
// 2 (y n + x) + 1) cut into quadrants: cluster 0 bottom left, 1 bottom right, 2 top left,
// 3 top right (numbered in order of first face).
std::vector<ClusterId> Quadrants(int n) {
  std::vector<ClusterId> labels;
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      const uint32_t quadrant = (y >= n / 2 ? 2 : 0) + (x >= n / 2 ? 1 : 0);
      labels.push_back(ClusterId(quadrant));
      labels.push_back(ClusterId(quadrant));
    }
  }
  return labels;
}

double HueOf(const std::array<uint8_t, 3>& colour) {
  return ToHsv(colour[0], colour[1], colour[2]).hue;
}

size_t CountPixels(const RgbaImage& image, const std::array<uint8_t, 3>& colour) {
  size_t count = 0;
  for (size_t i = 0; i < image.rgba.size(); i += 4) {
    if (image.rgba[i] == colour[0] && image.rgba[i + 1] == colour[1] &&
        image.rgba[i + 2] == colour[2]) {
      ++count;
    }
  }
  return count;
}

// Every expected hue is found once, and nothing else.
void ExpectHues(const std::vector<HueGroup>& found, const std::vector<double>& expected) {
  ASSERT_EQ(found.size(), expected.size());
  for (double hue : expected) {
    int matches = 0;
    for (const HueGroup& group : found) matches += HueDistance(group.hue, hue) < 3.0 ? 1 : 0;
    EXPECT_EQ(matches, 1) << "hue " << hue;
  }
}

TEST(ColourClustersTest, QuadrantsGetFourColoursAndBorderEdges) {
  const TriangleMesh mesh = Grid(4);
  const FaceAdjacency adjacency = AdjacencyOf(mesh);
  absl::StatusOr<ClusterPreviewColours> colours = ColourClusters(adjacency, Quadrants(4));
  ASSERT_TRUE(colours.ok()) << colours.status();
  EXPECT_EQ(colours->cluster_count, 4u);
  ASSERT_EQ(colours->cluster_colour.size(), 4u);
  const std::set<std::array<uint8_t, 3>> distinct(colours->cluster_colour.begin(),
                                                  colours->cluster_colour.end());
  EXPECT_EQ(distinct.size(), 4u);
  // The quadrants meet along x = 2 and y = 2: 4 + 4 edges, each seen from both faces.
  int border_bits = 0;
  for (uint32_t packed : colours->face) border_bits += __builtin_popcount(packed >> 24);
  EXPECT_EQ(border_bits, 16);
  // A face's colour bits are its cluster's colour.
  const std::vector<ClusterId> labels = Quadrants(4);
  for (size_t f = 0; f < colours->face.size(); ++f) {
    const auto& c = colours->cluster_colour[labels[f].value()];
    EXPECT_EQ(colours->face[f] & 0xffffff, c[0] | (c[1] << 8) | (c[2] << 16)) << "face " << f;
  }
}

TEST(ColourClustersTest, NeighbouringClustersDifferClearly) {
  // 32 strips of a 32 x 32 grid, each touching the next: every neighbouring pair at least
  // 60 apart in RGB (the palette's nearest pairs are much closer than that, so the greedy
  // choice is what keeps neighbours apart).
  const int n = 32;
  const TriangleMesh mesh = Grid(n);
  std::vector<ClusterId> labels;
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < 2 * n; ++x) labels.push_back(ClusterId(static_cast<uint32_t>(x / 2)));
  }
  absl::StatusOr<ClusterPreviewColours> colours = ColourClusters(AdjacencyOf(mesh), labels);
  ASSERT_TRUE(colours.ok()) << colours.status();
  ASSERT_EQ(colours->cluster_count, 32u);
  const std::set<std::array<uint8_t, 3>> distinct(colours->cluster_colour.begin(),
                                                  colours->cluster_colour.end());
  EXPECT_EQ(distinct.size(), 32u);
  for (int c = 0; c + 1 < n; ++c) {
    const auto& a = colours->cluster_colour[c];
    const auto& b = colours->cluster_colour[c + 1];
    double d2 = 0;
    for (int i = 0; i < 3; ++i) d2 += (double(a[i]) - b[i]) * (double(a[i]) - b[i]);
    EXPECT_GT(std::sqrt(d2), 60.0) << "strips " << c << " and " << c + 1;
  }
}

TEST(ColourClustersTest, RefusesLabelsOfAnotherMeshAndGreysFacesWithoutCluster) {
  const TriangleMesh mesh = Grid(2);
  const FaceAdjacency adjacency = AdjacencyOf(mesh);
  std::vector<ClusterId> labels(7, ClusterId(0));
  absl::StatusOr<ClusterPreviewColours> wrong = ColourClusters(adjacency, labels);
  EXPECT_EQ(wrong.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(wrong.status().message(), HasSubstr("7 labels for a mesh of 8 faces"));
  labels.assign(8, ClusterId(5));
  labels[3] = ClusterId::Invalid();
  absl::StatusOr<ClusterPreviewColours> colours = ColourClusters(adjacency, labels);
  ASSERT_TRUE(colours.ok()) << colours.status();
  EXPECT_EQ(colours->cluster_count, 1u);
  const auto& grey = kPreviewNoCluster;
  EXPECT_EQ(colours->face[3], uint32_t{grey[0]} | (grey[1] << 8) | (grey[2] << 16));
}

TEST(ClusterPreviewTest, QuadrantsShowFourHuesBordersAndBackground) {
  std::unique_ptr<GlContext> context = MakeContext();
  ASSERT_NE(context, nullptr);
  const TriangleMesh mesh = Grid(8);
  const FaceAdjacency adjacency = AdjacencyOf(mesh);
  const std::vector<ClusterId> labels = Quadrants(8);
  ClusterPreviewOptions options = Sized(320, 240);
  absl::StatusOr<RgbaImage> image =
      RenderClusterPreview(*context, mesh, adjacency, labels, options);
  ASSERT_TRUE(image.ok()) << image.status();
  EXPECT_EQ(image->width, 320u);
  EXPECT_EQ(image->height, 240u);
  ASSERT_EQ(image->rgba.size(), 320u * 240u * 4u);
  absl::StatusOr<ClusterPreviewColours> colours = ColourClusters(adjacency, labels);
  ASSERT_TRUE(colours.ok());
  std::vector<double> hues;
  for (const auto& colour : colours->cluster_colour) hues.push_back(HueOf(colour));
  ExpectHues(DistinctHues(*image), hues);
  // The corner is background; the borders between quadrants are drawn.
  const uint8_t* corner = image->pixel(0, 0);
  EXPECT_EQ(corner[0], kPreviewBackground[0]);
  EXPECT_EQ(corner[1], kPreviewBackground[1]);
  EXPECT_EQ(corner[2], kPreviewBackground[2]);
  EXPECT_GT(CountPixels(*image, kPreviewBorder), 100u);
  EXPECT_GT(CountPixels(*image, kPreviewBackground), 320u * 240u / 20);
}

TEST(ClusterPreviewTest, OneClusterHasOneHueAndNoBorder) {
  std::unique_ptr<GlContext> context = MakeContext();
  ASSERT_NE(context, nullptr);
  const TriangleMesh mesh = Grid(8);
  const std::vector<ClusterId> labels(mesh.num_faces(), ClusterId(3));
  ClusterPreviewOptions options = Sized(200, 200);
  absl::StatusOr<RgbaImage> image =
      RenderClusterPreview(*context, mesh, AdjacencyOf(mesh), labels, options);
  ASSERT_TRUE(image.ok()) << image.status();
  EXPECT_EQ(DistinctHues(*image).size(), 1u);
  EXPECT_EQ(CountPixels(*image, kPreviewBorder), 0u);
}

// MakeCube(4) with six planar clusters, one per side (+x, +y, +z, -x, -y, -z).
struct CubeBySide {
  CubeBySide() : cube(MakeCube(4)), adjacency(AdjacencyOf(cube.mesh)) {
    for (int side : cube.side) labels.push_back(ClusterId(static_cast<uint32_t>(side)));
  }
  const TriangleMesh& mesh() const { return cube.mesh; }
  mlclust::testing::SubdividedCube cube;
  FaceAdjacency adjacency;
  std::vector<ClusterId> labels;
};

// Renders `cube` with `options`: the image (kept in `image`) must show exactly the hues of
// the three clusters `sides` (of six).
void ExpectSidesShown(GlContext& context, const CubeBySide& cube,
                      const ClusterPreviewOptions& options, std::array<uint32_t, 3> sides,
                      RgbaImage& image) {
  absl::StatusOr<RgbaImage> rendered =
      RenderClusterPreview(context, cube.mesh(), cube.adjacency, cube.labels, options);
  ASSERT_TRUE(rendered.ok()) << rendered.status();
  image = *std::move(rendered);
  absl::StatusOr<ClusterPreviewColours> colours = ColourClusters(cube.adjacency, cube.labels);
  ASSERT_TRUE(colours.ok());
  ASSERT_EQ(colours->cluster_count, 6u);
  ExpectHues(DistinctHues(image),
             {HueOf(colours->cluster_colour[sides[0]]), HueOf(colours->cluster_colour[sides[1]]),
              HueOf(colours->cluster_colour[sides[2]])});
}

TEST(ClusterPreviewTest, CubeBySideShowsTheThreeSidesFacingTheCamera) {
  std::unique_ptr<GlContext> context = MakeContext();
  ASSERT_NE(context, nullptr);
  // The three-quarter view from the +x, +y, +z octant sees the first three sides, and the
  // depth test hides the rest.
  const CubeBySide cube;
  RgbaImage image;
  ASSERT_NO_FATAL_FAILURE(ExpectSidesShown(*context, cube, Sized(256, 256), {0, 1, 2}, image));
  // Lambert shading: the three visible sides face the light differently, so they differ
  // in brightness as well.
  EXPECT_GT(CountPixels(image, kPreviewBorder), 0u);
}

TEST(ClusterPreviewTest, CameraFromTheOtherOctantShowsTheOtherThreeSides) {
  std::unique_ptr<GlContext> context = MakeContext();
  ASSERT_NE(context, nullptr);
  const CubeBySide cube;
  ClusterPreviewOptions options = Sized(256, 256);
  options.azimuth_degrees = 215;    // from -x, -z
  options.elevation_degrees = -25;  // and below: -y
  RgbaImage image;
  ASSERT_NO_FATAL_FAILURE(ExpectSidesShown(*context, cube, options, {3, 4, 5}, image));
  options.elevation_degrees = 90;  // straight down: no up direction
  EXPECT_EQ(RenderClusterPreview(*context, cube.mesh(), cube.adjacency, cube.labels, options)
                .status()
                .code(),
            absl::StatusCode::kInvalidArgument);
}

TEST(ClusterPreviewTest, ChunkedDrawIsTheSamePicture) {
  // Buffers capped at 1 KiB: the grid's 128 faces go in two chunks of 85 and 43.
  std::unique_ptr<GlContext> chunked = ContextWithBuffersOf(1024);
  ASSERT_NE(chunked, nullptr);
  const TriangleMesh mesh = Grid(8);
  const FaceAdjacency adjacency = AdjacencyOf(mesh);
  ClusterPreviewOptions options = Sized(160, 120);
  absl::StatusOr<RgbaImage> in_chunks =
      RenderClusterPreview(*chunked, mesh, adjacency, Quadrants(8), options);
  ASSERT_TRUE(in_chunks.ok()) << in_chunks.status();
  chunked.reset();
  std::unique_ptr<GlContext> whole = MakeContext();
  ASSERT_NE(whole, nullptr);
  absl::StatusOr<RgbaImage> at_once =
      RenderClusterPreview(*whole, mesh, adjacency, Quadrants(8), options);
  ASSERT_TRUE(at_once.ok()) << at_once.status();
  size_t differ = 0;
  for (size_t i = 0; i < at_once->rgba.size(); ++i)
    differ += in_chunks->rgba[i] != at_once->rgba[i];
  EXPECT_EQ(differ, 0u);
}

TEST(ClusterPreviewTest, RefusesSizesOutOfRange) {
  std::unique_ptr<GlContext> context = MakeContext();
  ASSERT_NE(context, nullptr);
  const TriangleMesh mesh = Grid(2);
  const std::vector<ClusterId> labels(mesh.num_faces(), ClusterId(0));
  const FaceAdjacency adjacency = AdjacencyOf(mesh);
  for (auto [width, height] : {std::pair<uint32_t, uint32_t>{0, 100}, {100, 0}, {1u << 20, 64}}) {
    ClusterPreviewOptions options = Sized(width, height);
    absl::StatusOr<RgbaImage> image =
        RenderClusterPreview(*context, mesh, adjacency, labels, options);
    EXPECT_EQ(image.status().code(), absl::StatusCode::kInvalidArgument) << width << "x" << height;
    EXPECT_THAT(image.status().message(), HasSubstr("pixels"));
  }
}

TEST(ClusterPreviewTest, MeshAtOnePointStillGivesAPicture) {
  std::unique_ptr<GlContext> context = MakeContext();
  ASSERT_NE(context, nullptr);
  // Zero-area faces (ValidateMesh accepts them): nothing to fit, no crash, a full picture.
  const TriangleMesh mesh = mlclust::testing::MakeMesh({2, 2, 2, 2, 2, 2, 2, 2, 2}, {0, 1, 2});
  ClusterPreviewOptions options = Sized(64, 48);
  absl::StatusOr<RgbaImage> image =
      RenderClusterPreview(*context, mesh, AdjacencyOf(mesh), std::vector{ClusterId(0)}, options);
  ASSERT_TRUE(image.ok()) << image.status();
  EXPECT_EQ(image->rgba.size(), 64u * 48u * 4u);
  EXPECT_GT(CountPixels(*image, kPreviewBackground), 64u * 48u / 2);
}

TEST(ClusterPreviewTest, VerticesOverOneBufferAreRefusedClearly) {
  // A context whose storage buffers hold 64 bytes: Grid(8)'s 81 vertices (972 bytes) do
  // not fit, and the error says so instead of drawing part of the mesh.
  std::unique_ptr<GlContext> context = ContextWithBuffersOf(64);
  ASSERT_NE(context, nullptr);
  const TriangleMesh mesh = Grid(8);
  absl::StatusOr<RgbaImage> image =
      RenderClusterPreview(*context, mesh, AdjacencyOf(mesh), Quadrants(8));
  EXPECT_EQ(image.status().code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(image.status().message(), HasSubstr("81 vertices (972 bytes) do not fit"));
}

TEST(PngCodecTest, RoundTripsAndRefusesBrokenFiles) {
  RgbaImage image;
  image.width = 7;
  image.height = 3;
  for (uint32_t i = 0; i < 21; ++i) {
    image.rgba.insert(image.rgba.end(), {static_cast<uint8_t>(i * 11), static_cast<uint8_t>(i),
                                         static_cast<uint8_t>(255 - i), 255});
  }
  absl::StatusOr<std::string> png = EncodePng(image);
  ASSERT_TRUE(png.ok()) << png.status();
  EXPECT_EQ(png->substr(1, 3), "PNG");
  absl::StatusOr<RgbaImage> decoded = DecodePng(*png);
  ASSERT_TRUE(decoded.ok()) << decoded.status();
  EXPECT_EQ(decoded->width, 7u);
  EXPECT_EQ(decoded->height, 3u);
  EXPECT_TRUE(decoded->rgba == image.rgba);

  EXPECT_EQ(DecodePng("not a png").status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_FALSE(DecodePng(png->substr(0, png->size() / 2)).ok());
  EXPECT_EQ(DecodePng(*png, /*max_pixels=*/20).status().code(), absl::StatusCode::kInvalidArgument);
  image.rgba.pop_back();
  EXPECT_EQ(EncodePng(image).status().code(), absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace mlclust::gpu
