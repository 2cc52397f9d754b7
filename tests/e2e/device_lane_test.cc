// Issue 23's device bugs through a real server on loopback, the GPU on (llvmpipe where there
// is no GPU) and two CPU workers (serve --workers 2):
//   (a) a points job with --device gpu runs on the GL worker's GPU (it was sent to a CPU
//       worker and refused there with "this server has no GPU");
//   (c) a mesh job with --device gpu whose cluster stage has no GPU implementation for its
//       options says so before any stage, its cluster stage's events name the CPU, and Done
//       names each stage's device.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "client/client.h"
#include "core/io/draco_codec.h"
#include "mlclust/v1/mlclust.grpc.pb.h"
#include "server/server.h"
#include "tests/fixtures/test_meshes.h"
#include "tests/fixtures/test_server.h"

namespace mlclust {
namespace {

using ::testing::HasSubstr;

class DeviceLaneTest : public ::testing::Test {
 protected:
  void SetUp() override {
    server::ServerOptions options;
    options.gpu = server::GpuMode::kOn;
    options.cpu_workers = 2;
    absl::StatusOr<std::unique_ptr<server::Server>> started = testing::StartLocal(options);
    ASSERT_TRUE(started.ok()) << started.status();
    server_ = *std::move(started);
    channel_ = testing::ChannelTo(*server_);
    renderer_ = server_->gl_renderer();
    ASSERT_FALSE(renderer_.empty());
  }

  absl::StatusOr<client::JobResult> Run(const v1::JobSpec& spec, const std::string& input,
                                        std::vector<v1::Progress>& progress) {
    client::RunOptions options;
    options.on_event = [&progress](const v1::JobEvent& event) {
      if (event.has_progress()) progress.push_back(event.progress());
    };
    return client::RunJob(channel_, spec, input, options);
  }

  // The device of `stage`'s last Progress ("none" without one).
  static std::string DeviceOf(const std::vector<v1::Progress>& progress, const std::string& stage) {
    std::string device = "none";
    for (const v1::Progress& p : progress) {
      if (p.stage() == stage) device = p.device();
    }
    return device;
  }

  std::unique_ptr<server::Server> server_;
  std::shared_ptr<grpc::Channel> channel_;
  std::string renderer_;
};

TEST_F(DeviceLaneTest, PointsWithDeviceGpuRunOnTheGlWorkersGpuBesideCpuWorkers) {
  v1::JobSpec spec;
  spec.set_input_kind(v1::INPUT_KIND_POINTS_F32);
  spec.set_point_dims(3);
  spec.set_algorithm(v1::ALGORITHM_PML);
  spec.set_device("gpu");
  (*spec.mutable_options())["optimizer"] = "none";  // PML's levels, merges only
  std::vector<v1::Progress> progress;
  absl::StatusOr<client::JobResult> result = Run(spec, testing::BlobBytes(2000, 7), progress);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_EQ(DeviceOf(progress, "cluster"), renderer_);
  EXPECT_EQ(result->done.device(), renderer_);
  EXPECT_GT(result->hierarchy.num_levels(), 1u);
}

TEST_F(DeviceLaneTest, MeshWithDeviceGpuSaysWhichStagesRunOnTheCpuAndWhy) {
  // PML's default optimiser, EMLO, has no GPU implementation: its levels run on the CPU,
  // its face measures on the GPU.
  v1::JobSpec spec = testing::MeshSpec(v1::ALGORITHM_PML, 10);
  spec.set_device("gpu");
  std::vector<v1::Progress> progress;
  absl::StatusOr<client::JobResult> result =
      Run(spec, *EncodeMeshToDraco(testing::Grid(20)), progress);
  ASSERT_TRUE(result.ok()) << result.status();
  ASSERT_FALSE(progress.empty());
  size_t first = 0;
  while (first < progress.size() && progress[first].stage() == "queued") ++first;
  ASSERT_LT(first, progress.size());
  EXPECT_EQ(progress[first].stage(), "plan");
  EXPECT_THAT(progress[first].message(), HasSubstr("cluster on the CPU: the GPU's PML optimises "
                                                   "with BB (optimizer bb) or not at all"));
  EXPECT_THAT(progress[first].message(), HasSubstr("measures on " + renderer_));
  EXPECT_EQ(DeviceOf(progress, "measures"), renderer_);
  EXPECT_EQ(DeviceOf(progress, "cluster"), "cpu");
  // Done: each stage as it ran; Done.device (for older clients) the renderer that ran one.
  ASSERT_EQ(result->done.devices_size(), 2);
  EXPECT_EQ(result->done.devices(0).stage(), "measures");
  EXPECT_EQ(result->done.devices(0).device(), renderer_);
  EXPECT_EQ(result->done.devices(1).stage(), "cluster");
  EXPECT_EQ(result->done.devices(1).device(), "cpu");
  EXPECT_EQ(result->done.device(), renderer_);
}

}  // namespace
}  // namespace mlclust
