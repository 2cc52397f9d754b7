// End-to-end tests of the GPU stages through the server (llvmpipe where there is no GPU):
// BB with --device gpu runs its decide stage on the GL context and says so in its events;
// a GL failure injected into a pass is a clean job error and the server keeps serving.
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
#include "tests/fixtures/test_server.h"

namespace mlclust {
namespace {

class GpuStagesTest : public testing::GpuServerTest {
 protected:
  static v1::JobSpec BbSpec(const std::string& device) {
    v1::JobSpec spec = testing::MeshSpec(v1::ALGORITHM_BB, 100);
    spec.set_device(device);
    return spec;
  }
};

TEST_F(GpuStagesTest, BbWithDeviceGpuRunsTheDecideStageOnTheGlContext) {
  const std::string renderer = server_->gl_renderer();
  ASSERT_FALSE(renderer.empty());
  std::vector<v1::Progress> progress;
  absl::StatusOr<client::JobResult> gpu = Run(BbSpec("gpu"), &progress);
  ASSERT_TRUE(gpu.ok()) << gpu.status();
  absl::StatusOr<client::JobResult> cpu = Run(BbSpec("cpu"));
  ASSERT_TRUE(cpu.ok()) << cpu.status();

  // The cluster stage's events name the renderer; Done names it too.
  bool cluster_on_gpu = false;
  for (const v1::Progress& p : progress) {
    if (p.stage() == "cluster") {
      EXPECT_EQ(p.device(), renderer) << p.message();
      cluster_on_gpu = true;
    }
  }
  EXPECT_TRUE(cluster_on_gpu);
  EXPECT_EQ(gpu->done.device(), renderer);
  EXPECT_EQ(cpu->done.device(), "cpu");

  // Same seeding, energies within 1% (identical on llvmpipe).
  ASSERT_EQ(gpu->hierarchy.num_levels(), 2u);
  ASSERT_EQ(cpu->hierarchy.num_levels(), 2u);
  EXPECT_EQ(gpu->hierarchy.energy(0), cpu->hierarchy.energy(0));
  EXPECT_LT(gpu->hierarchy.energy(1), gpu->hierarchy.energy(0));
  EXPECT_NEAR(gpu->hierarchy.energy(1), cpu->hierarchy.energy(1), 0.01 * cpu->hierarchy.energy(1));
}

TEST_F(GpuStagesTest, InjectedGlFailureIsACleanJobErrorAndTheServerKeepsServing) {
  ExpectFailsInPass(BbSpec("gpu"), "bb decide");
  // A CPU job is untouched by the hook; after it is cleared the GPU serves again.
  absl::StatusOr<client::JobResult> cpu = Run(BbSpec("cpu"));
  EXPECT_TRUE(cpu.ok()) << cpu.status();
  ExpectRunsWithTheHookCleared(BbSpec("gpu"));
}

TEST_F(GpuStagesTest, LnKmeansAndKmeansWithDeviceGpu) {
  const std::string points = testing::BlobBytes(6000, 11);
  for (v1::Algorithm algorithm : {v1::ALGORITHM_LN_KMEANS, v1::ALGORITHM_KMEANS}) {
    v1::JobSpec spec;
    spec.set_input_kind(v1::INPUT_KIND_POINTS_F32);
    spec.set_point_dims(3);
    spec.set_algorithm(algorithm);
    spec.set_clusters(25);
    spec.set_device("gpu");
    absl::StatusOr<client::JobResult> gpu = client::RunJob(channel_, spec, points);
    ASSERT_TRUE(gpu.ok()) << gpu.status();
    spec.set_device("cpu");
    absl::StatusOr<client::JobResult> cpu = client::RunJob(channel_, spec, points);
    ASSERT_TRUE(cpu.ok()) << cpu.status();
    EXPECT_EQ(gpu->done.device(), server_->gl_renderer());
    EXPECT_EQ(cpu->done.device(), "cpu");
    ASSERT_EQ(gpu->hierarchy.num_levels(), 2u);
    ASSERT_EQ(cpu->hierarchy.num_levels(), 2u);
    // Issue 10: inertia within 0.5%.
    EXPECT_NEAR(gpu->hierarchy.energy(1), cpu->hierarchy.energy(1),
                0.005 * cpu->hierarchy.energy(1))
        << v1::Algorithm_Name(algorithm);
    EXPECT_LE(gpu->hierarchy.energy(1), gpu->hierarchy.energy(0));
  }
}

}  // namespace
}  // namespace mlclust
