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
#include <optional>
#include <string>
#include <vector>

#include "client/client.h"
#include "mlclust/v1/mlclust.grpc.pb.h"
#include "server/server.h"
#include "tests/fixtures/level_checks.h"
#include "tests/fixtures/test_server.h"

namespace mlclust {
namespace {

class PointsPmlGpuTest : public testing::GpuServerTest {
 protected:
  void SetUp() override {
    ASSERT_NO_FATAL_FAILURE(GpuServerTest::SetUp());
    input_ = testing::BlobBytes(6000, 17);  // 6,000 points around 20 centres
  }

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
};

TEST_F(PointsPmlGpuTest, DeviceGpuRunsTheVoxelStartAndTheLevelsOnTheGlContext) {
  std::optional<client::JobResult> gpu, cpu;
  ASSERT_NO_FATAL_FAILURE(RunOnGpuAndCpu(Spec("gpu", "none"), Spec("cpu", "none"), gpu, cpu));
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
    ExpectFailsInPass(Spec("gpu", "none"), pass);
  }
  ExpectRunsWithTheHookCleared(Spec("gpu", "none"));
}

}  // namespace
}  // namespace mlclust
