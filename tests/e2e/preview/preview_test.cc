// The preview end to end (JobSpec.preview): a real server draws the level through its GL
// context (llvmpipe where there is no GPU) and sends a PNG before Done.
#include "server/preview.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <vector>

#include "client/client.h"
#include "core/io/draco_codec.h"
#include "gpu/render/png_codec.h"
#include "grpcpp/grpcpp.h"
#include "mlclust/v1/mlclust.grpc.pb.h"
#include "server/server.h"
#include "tests/fixtures/image_hues.h"
#include "tests/fixtures/test_meshes.h"
#include "tests/fixtures/test_server.h"

namespace mlclust {
namespace {

using ::mlclust::testing::DistinctHues;
using ::mlclust::testing::MakeCube;
using ::testing::HasSubstr;

using ::mlclust::testing::ChannelTo;
using ::mlclust::testing::StartServer;

// ML with the planar energy on a cube: the six sides are its level with 6 clusters (a
// merge inside a side costs nothing, across an edge it does).
v1::JobSpec CubeSpec(uint32_t width, uint32_t height, uint32_t cluster_count) {
  v1::JobSpec spec;
  spec.set_input_kind(v1::INPUT_KIND_DRACO_MESH);
  spec.set_algorithm(v1::ALGORITHM_ML);
  spec.set_energy(v1::ENERGY_PLANAR);
  spec.mutable_preview()->set_width(width);
  spec.mutable_preview()->set_height(height);
  spec.mutable_preview()->set_cluster_count(cluster_count);
  return spec;
}

std::string CubeBytes() {
  absl::StatusOr<std::string> bytes = EncodeMeshToDraco(MakeCube(3).mesh);
  EXPECT_TRUE(bytes.ok()) << bytes.status();
  return bytes.ok() ? *bytes : std::string();
}

TEST(PreviewEndToEndTest, CubeOfSixSidesShowsThreeColoursBeforeDone) {
  std::unique_ptr<server::Server> server = StartServer();
  ASSERT_NE(server, nullptr);
  if (server->gl_renderer().empty()) GTEST_FAIL() << server->gl_unavailable_reason();
  std::vector<v1::JobEvent::EventCase> order;
  client::RunOptions options;
  options.on_event = [&](const v1::JobEvent& event) { order.push_back(event.event_case()); };
  absl::StatusOr<client::JobResult> result =
      client::RunJob(ChannelTo(*server), CubeSpec(320, 240, 6), CubeBytes(), options);
  ASSERT_TRUE(result.ok()) << result.status();
  const v1::Preview& preview = result->preview;
  EXPECT_EQ(preview.width(), 320u);
  EXPECT_EQ(preview.height(), 240u);
  EXPECT_EQ(preview.cluster_count(), 6u);
  EXPECT_EQ(preview.device(), server->gl_renderer());
  EXPECT_GT(result->done.seconds_preview(), 0.0);
  absl::StatusOr<gpu::RgbaImage> image = gpu::DecodePng(preview.png());
  ASSERT_TRUE(image.ok()) << image.status();
  EXPECT_EQ(image->width, 320u);
  EXPECT_EQ(image->height, 240u);
  // The three sides facing the camera, one colour each.
  EXPECT_EQ(DistinctHues(*image).size(), 3u);
  // The preview comes after the levels and right before Done.
  ASSERT_GE(order.size(), 2u);
  EXPECT_EQ(order[order.size() - 2], v1::JobEvent::kPreview);
  EXPECT_EQ(order.back(), v1::JobEvent::kDone);
}

TEST(PreviewEndToEndTest, WithoutClusterCountTheFinalLevelIsDrawn) {
  std::unique_ptr<server::Server> server = StartServer();
  ASSERT_NE(server, nullptr);
  absl::StatusOr<client::JobResult> result =
      client::RunJob(ChannelTo(*server), CubeSpec(0, 0, 0), CubeBytes());
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_EQ(result->preview.width(), server::kDefaultPreviewWidth);
  EXPECT_EQ(result->preview.height(), server::kDefaultPreviewHeight);
  EXPECT_EQ(result->preview.cluster_count(), result->done.final_clusters());
  absl::StatusOr<gpu::RgbaImage> image = gpu::DecodePng(result->preview.png());
  ASSERT_TRUE(image.ok()) << image.status();
  EXPECT_EQ(DistinctHues(*image).size(), 1u);  // one cluster: one colour
}

TEST(PreviewEndToEndTest, CpuWorkersHandPreviewJobsToTheGlWorker) {
  server::ServerOptions options;
  options.cpu_workers = 2;
  std::unique_ptr<server::Server> server = StartServer(options);
  ASSERT_NE(server, nullptr);
  absl::StatusOr<client::JobResult> result =
      client::RunJob(ChannelTo(*server), CubeSpec(64, 64, 6), CubeBytes());
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_EQ(result->preview.cluster_count(), 6u);
}

TEST(PreviewEndToEndTest, RefusedClearlyBeforeTheJobRuns) {
  std::unique_ptr<server::Server> server = StartServer();
  ASSERT_NE(server, nullptr);
  absl::StatusOr<client::JobResult> small =
      client::RunJob(ChannelTo(*server), CubeSpec(8, 240, 6), CubeBytes());
  EXPECT_EQ(small.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(small.status().message(), HasSubstr("preview.width: 8 pixels; give 16 to 4096"));

  v1::JobSpec steep = CubeSpec(32, 32, 6);
  steep.mutable_preview()->set_elevation_degrees(95);
  absl::StatusOr<client::JobResult> from_above =
      client::RunJob(ChannelTo(*server), steep, CubeBytes());
  EXPECT_EQ(from_above.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(from_above.status().message(), HasSubstr("elevation 95 degrees; give -89 to 89"));

  v1::JobSpec points;
  points.set_input_kind(v1::INPUT_KIND_POINTS_F32);
  points.set_point_dims(1);
  points.mutable_preview();
  const float values[4] = {0, 1, 5, 6};
  absl::StatusOr<client::JobResult> on_points = client::RunJob(
      ChannelTo(*server), points, std::string(reinterpret_cast<const char*>(values), 16));
  EXPECT_EQ(on_points.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(on_points.status().message(), HasSubstr("preview: only for meshes"));

  // The server keeps serving.
  absl::StatusOr<client::JobResult> fine =
      client::RunJob(ChannelTo(*server), CubeSpec(32, 32, 6), CubeBytes());
  EXPECT_TRUE(fine.ok()) << fine.status();
}

TEST(PreviewEndToEndTest, ServerWithoutGlFailsThePreviewJobClearly) {
  server::ServerOptions options;
  options.gpu = server::GpuMode::kOff;
  std::unique_ptr<server::Server> server = StartServer(options);
  ASSERT_NE(server, nullptr);
  absl::StatusOr<client::JobResult> result =
      client::RunJob(ChannelTo(*server), CubeSpec(320, 240, 6), CubeBytes());
  EXPECT_EQ(result.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(result.status().message(), HasSubstr("GL context"));
  // The same job without a preview runs.
  v1::JobSpec spec = CubeSpec(0, 0, 0);
  spec.clear_preview();
  absl::StatusOr<client::JobResult> plain = client::RunJob(ChannelTo(*server), spec, CubeBytes());
  EXPECT_TRUE(plain.ok()) << plain.status();
  EXPECT_TRUE(plain->preview.png().empty());
}

TEST(PreviewSizeTest, ParsesWidthByHeightAndRefusesTheRest) {
  absl::StatusOr<std::pair<uint32_t, uint32_t>> size = server::ParsePreviewSize("800x600", "--s");
  ASSERT_TRUE(size.ok()) << size.status();
  EXPECT_EQ(size->first, 800u);
  EXPECT_EQ(size->second, 600u);
  for (const char* bad :
       {"800", "800x", "x600", "axb", "800x600x2", "-5x10", "10x10", "5000x100", "100x4097", ""}) {
    absl::StatusOr<std::pair<uint32_t, uint32_t>> parsed = server::ParsePreviewSize(bad, "--s");
    EXPECT_EQ(parsed.status().code(), absl::StatusCode::kInvalidArgument) << bad;
    EXPECT_THAT(parsed.status().message(), HasSubstr("--s")) << bad;
  }
}

TEST(PreviewSizeTest, ParsesTheViewAndRefusesTheRest) {
  absl::StatusOr<std::pair<float, float>> view = server::ParsePreviewView("215,-20.5", "--v");
  ASSERT_TRUE(view.ok()) << view.status();
  EXPECT_EQ(view->first, 215.0f);
  EXPECT_EQ(view->second, -20.5f);
  for (const char* bad : {"215", "215,", ",20", "a,b", "10,90", "400,0", "nan,0", "0,inf", ""}) {
    absl::StatusOr<std::pair<float, float>> parsed = server::ParsePreviewView(bad, "--v");
    EXPECT_EQ(parsed.status().code(), absl::StatusCode::kInvalidArgument) << bad;
    EXPECT_THAT(parsed.status().message(), HasSubstr("--v")) << bad;
  }
}

}  // namespace
}  // namespace mlclust
