// End-to-end: HC's steps on the GPU through the server (llvmpipe where there is no GPU).
// --device gpu --algo hc with cvd runs the steps on the GL context
// (gpu/stages/hierarchy_gpu.h), names the renderer in the cluster stage's events and in
// Done, and streams the CPU's levels exactly; with planar (no GPU merge cost) the cluster
// stage stays on the CPU and says so; a GL failure injected into an HC pass is a clean job
// error and the server keeps serving.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <string>
#include <vector>

#include "client/client.h"
#include "core/io/draco_codec.h"
#include "core/io/mesh_io.h"
#include "mlclust/v1/mlclust.grpc.pb.h"
#include "server/server.h"
#include "tests/fixtures/test_meshes.h"

namespace mlclust {
namespace {

using ::testing::HasSubstr;

class HcGpuTest : public ::testing::Test {
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
    absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(testing::DataPath("fandisk.off"));
    ASSERT_TRUE(mesh.ok()) << mesh.status();
    absl::StatusOr<std::string> bytes = EncodeMeshToDraco(*mesh);
    ASSERT_TRUE(bytes.ok()) << bytes.status();
    fandisk_ = *std::move(bytes);
  }
  void TearDown() override { unsetenv("MLCLUST_GPU_FAIL_PASS"); }

  static v1::JobSpec HcSpec(const std::string& device, v1::Energy energy = v1::ENERGY_CVD) {
    v1::JobSpec spec;
    spec.set_input_kind(v1::INPUT_KIND_DRACO_MESH);
    spec.set_algorithm(v1::ALGORITHM_HC);
    spec.set_energy(energy);
    spec.set_clusters(20);
    spec.set_device(device);
    return spec;
  }

  absl::StatusOr<client::JobResult> Run(const v1::JobSpec& spec,
                                        std::vector<v1::Progress>* progress = nullptr) {
    client::RunOptions options;
    options.on_event = [progress](const v1::JobEvent& event) {
      if (progress != nullptr && event.has_progress()) progress->push_back(event.progress());
    };
    return client::RunJob(channel_, spec, fandisk_, options);
  }

  std::unique_ptr<server::Server> server_;
  std::shared_ptr<grpc::Channel> channel_;
  std::string fandisk_;
};

std::string ClusterDevice(const std::vector<v1::Progress>& progress) {
  std::string device = "none";
  for (const v1::Progress& p : progress) {
    if (p.stage() == "cluster") device = p.device();
  }
  return device;
}

TEST_F(HcGpuTest, DeviceGpuRunsTheHcStepsOnTheGlContext) {
  const std::string renderer = server_->gl_renderer();
  ASSERT_FALSE(renderer.empty());
  std::vector<v1::Progress> progress;
  absl::StatusOr<client::JobResult> gpu = Run(HcSpec("gpu"), &progress);
  ASSERT_TRUE(gpu.ok()) << gpu.status();
  EXPECT_EQ(ClusterDevice(progress), renderer);
  EXPECT_EQ(gpu->done.device(), renderer);
  absl::StatusOr<client::JobResult> cpu = Run(HcSpec("cpu"));
  ASSERT_TRUE(cpu.ok()) << cpu.status();
  EXPECT_EQ(cpu->done.device(), "cpu");
  // The same levels: counts, energies and labels at every level.
  ASSERT_EQ(gpu->hierarchy.num_levels(), cpu->hierarchy.num_levels());
  ASSERT_GT(gpu->hierarchy.num_levels(), 10000u);
  std::vector<ClusterId> gpu_labels(gpu->hierarchy.start_labels().begin(),
                                    gpu->hierarchy.start_labels().end());
  std::vector<ClusterId> cpu_labels(cpu->hierarchy.start_labels().begin(),
                                    cpu->hierarchy.start_labels().end());
  size_t same_labels = 0;
  for (size_t l = 0; l < gpu->hierarchy.num_levels(); ++l) {
    EXPECT_EQ(gpu->hierarchy.cluster_count(l), cpu->hierarchy.cluster_count(l));
    EXPECT_EQ(gpu->hierarchy.energy(l), cpu->hierarchy.energy(l)) << "level " << l;
    if (l > 0) {
      ASSERT_TRUE(gpu->hierarchy.StepLabels(gpu_labels, l - 1, l).ok());
      ASSERT_TRUE(cpu->hierarchy.StepLabels(cpu_labels, l - 1, l).ok());
    }
    same_labels += gpu_labels == cpu_labels ? 1 : 0;
  }
  EXPECT_EQ(same_labels, gpu->hierarchy.num_levels());
  EXPECT_EQ(gpu->hierarchy.cluster_count(gpu->hierarchy.num_levels() - 1), 20u);
}

// The GPU has the merge cost of the CVD energies only: with planar the steps stay on the
// CPU (chosen at plan time and named in the events), even with device gpu.
TEST_F(HcGpuTest, WithoutAGpuMergeCostTheStepsStayOnTheCpu) {
  std::vector<v1::Progress> progress;
  absl::StatusOr<client::JobResult> result = Run(HcSpec("gpu", v1::ENERGY_PLANAR), &progress);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_EQ(ClusterDevice(progress), "cpu");
}

TEST_F(HcGpuTest, InjectedGlFailureIsACleanJobErrorAndTheServerKeepsServing) {
  for (const char* pass : {"hc odes", "hc collapse", "hc triplets"}) {
    ASSERT_EQ(setenv("MLCLUST_GPU_FAIL_PASS", pass, 1), 0);
    absl::StatusOr<client::JobResult> failed = Run(HcSpec("gpu"));
    EXPECT_EQ(failed.status().code(), absl::StatusCode::kInternal) << pass;
    EXPECT_THAT(failed.status().message(), HasSubstr(absl::StrCat("GPU pass '", pass, "'")));
  }
  ASSERT_EQ(unsetenv("MLCLUST_GPU_FAIL_PASS"), 0);
  absl::StatusOr<client::JobResult> gpu = Run(HcSpec("gpu"));
  EXPECT_TRUE(gpu.ok()) << gpu.status();
}

}  // namespace
}  // namespace mlclust
