// End-to-end: PML for points on the GPU through the server (llvmpipe where there is no
// GPU). --device gpu --algo pml --optimizer none runs the voxel start and the levels on
// the GL context (gpu/stages/points_multilevel_gpu.h) and names the renderer in the
// cluster stage's events and in Done; the start is the CPU's; with LN k-means (not on the
// GPU) the levels stay on the CPU and say so; a GL failure injected into a pass is a
// clean job error and the server keeps serving.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include "client/client.h"
#include "mlclust/v1/mlclust.grpc.pb.h"
#include "server/server.h"

namespace mlclust {
namespace {

using ::testing::HasSubstr;

// 6,000 points around 20 centres, as float32 bytes (the wire's layout).
std::string BlobBytes() {
  std::mt19937 random(17);
  std::uniform_real_distribution<float> box(-30, 30);
  std::normal_distribution<float> spread(0, 1);
  std::vector<float> centres(60);
  for (float& c : centres) c = box(random);
  std::vector<float> values;
  for (uint32_t i = 0; i < 6000; ++i) {
    for (int j = 0; j < 3; ++j) values.push_back(centres[(i % 20) * 3 + j] + spread(random));
  }
  return std::string(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(float));
}

class PointsPmlGpuTest : public ::testing::Test {
 protected:
  void SetUp() override {
    server::ServerOptions options;
    options.listen_address = "127.0.0.1:0";
    options.log = false;
    options.gpu = server::GpuMode::kOn;
    absl::StatusOr<std::unique_ptr<server::Server>> started = server::Server::Start(options);
    ASSERT_TRUE(started.ok()) << started.status();
    server_ = *std::move(started);
    channel_ = client::Connect(absl::StrCat("127.0.0.1:", server_->port()));
    points_ = BlobBytes();
  }
  void TearDown() override { unsetenv("MLCLUST_GPU_FAIL_PASS"); }

  static v1::JobSpec Spec(const std::string& device, const std::string& optimizer) {
    v1::JobSpec spec;
    spec.set_input_kind(v1::INPUT_KIND_POINTS_F32);
    spec.set_point_dims(3);
    spec.set_algorithm(v1::ALGORITHM_PML);
    spec.set_clusters(20);
    spec.set_device(device);
    (*spec.mutable_options())["optimizer"] = optimizer;
    return spec;
  }

  absl::StatusOr<client::JobResult> Run(const v1::JobSpec& spec,
                                        std::vector<v1::Progress>* progress = nullptr) {
    client::RunOptions options;
    options.on_event = [progress](const v1::JobEvent& event) {
      if (progress != nullptr && event.has_progress()) progress->push_back(event.progress());
    };
    return client::RunJob(channel_, spec, points_, options);
  }

  std::unique_ptr<server::Server> server_;
  std::shared_ptr<grpc::Channel> channel_;
  std::string points_;
};

std::string ClusterDevice(const std::vector<v1::Progress>& progress) {
  std::string device = "none";
  for (const v1::Progress& p : progress) {
    if (p.stage() == "cluster") device = p.device();
  }
  return device;
}

TEST_F(PointsPmlGpuTest, DeviceGpuRunsTheVoxelStartAndTheLevelsOnTheGlContext) {
  const std::string renderer = server_->gl_renderer();
  ASSERT_FALSE(renderer.empty());
  std::vector<v1::Progress> progress;
  absl::StatusOr<client::JobResult> gpu = Run(Spec("gpu", "none"), &progress);
  ASSERT_TRUE(gpu.ok()) << gpu.status();
  EXPECT_EQ(ClusterDevice(progress), renderer);
  EXPECT_EQ(gpu->done.device(), renderer);
  absl::StatusOr<client::JobResult> cpu = Run(Spec("cpu", "none"));
  ASSERT_TRUE(cpu.ok()) << cpu.status();
  EXPECT_EQ(cpu->done.device(), "cpu");
  // The same start (labels and energy), the same lowest level (20 clusters), and there
  // the energy within 1%.
  const auto& g = gpu->hierarchy;
  const auto& c = cpu->hierarchy;
  ASSERT_GT(g.num_levels(), 3u);
  EXPECT_TRUE(std::equal(g.start_labels().begin(), g.start_labels().end(), c.start_labels().begin(),
                         c.start_labels().end()));
  EXPECT_EQ(g.cluster_count(0), c.cluster_count(0));
  EXPECT_EQ(g.energy(0), c.energy(0));
  EXPECT_EQ(g.cluster_count(g.num_levels() - 1), 20u);
  EXPECT_EQ(c.cluster_count(c.num_levels() - 1), 20u);
  EXPECT_NEAR(g.energy(g.num_levels() - 1), c.energy(c.num_levels() - 1),
              0.01 * c.energy(c.num_levels() - 1));
}

// The GPU has no LN k-means inside PML: with it the levels stay on the CPU (chosen at
// plan time and named in the events), even with device gpu.
TEST_F(PointsPmlGpuTest, WithLnKmeansTheLevelsStayOnTheCpu) {
  std::vector<v1::Progress> progress;
  absl::StatusOr<client::JobResult> result = Run(Spec("gpu", "lnkmeans"), &progress);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_EQ(ClusterDevice(progress), "cpu");
}

TEST_F(PointsPmlGpuTest, InjectedGlFailureIsACleanJobErrorAndTheServerKeepsServing) {
  for (const char* pass : {"voxel start", "points odes", "points neighbours"}) {
    ASSERT_EQ(setenv("MLCLUST_GPU_FAIL_PASS", pass, 1), 0);
    absl::StatusOr<client::JobResult> failed = Run(Spec("gpu", "none"));
    EXPECT_EQ(failed.status().code(), absl::StatusCode::kInternal) << pass;
    EXPECT_THAT(failed.status().message(), HasSubstr(absl::StrCat("GPU pass '", pass, "'")));
  }
  ASSERT_EQ(unsetenv("MLCLUST_GPU_FAIL_PASS"), 0);
  absl::StatusOr<client::JobResult> gpu = Run(Spec("gpu", "none"));
  EXPECT_TRUE(gpu.ok()) << gpu.status();
}

}  // namespace
}  // namespace mlclust
