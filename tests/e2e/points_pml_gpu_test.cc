// End-to-end: PML for points on the GPU through the server (llvmpipe where there is no
// GPU). --device gpu --algo pml --optimizer none runs the voxel start and the levels on
// the GL context (gpu/stages/points_multilevel_gpu.h) and names the renderer in the
// cluster stage's events and in Done; the start is the CPU's; with LN k-means
// (gpu/stages/points_optimise_gpu.h) device gpu runs the levels on the GPU too and auto
// on llvmpipe keeps them on the CPU; a GL failure injected into a pass is a clean job
// error and the server keeps serving.
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

  // `optimizer` with device gpu against device cpu: the cluster stage's events and Done
  // name the renderer; the same start (labels and energy), the same lowest level (20
  // clusters), and there the energy within 1%.
  void ExpectGpuLikeTheCpu(const std::string& optimizer) {
    std::optional<client::JobResult> gpu, cpu;
    ASSERT_NO_FATAL_FAILURE(
        RunOnGpuAndCpu(Spec("gpu", optimizer), Spec("cpu", optimizer), gpu, cpu));
    const auto& g = gpu->hierarchy;
    const auto& c = cpu->hierarchy;
    ASSERT_GT(g.num_levels(), 3u);
    EXPECT_TRUE(std::equal(g.start_labels().begin(), g.start_labels().end(),
                           c.start_labels().begin(), c.start_labels().end()));
    EXPECT_EQ(g.cluster_count(0), c.cluster_count(0));
    EXPECT_EQ(g.energy(0), c.energy(0));
    EXPECT_EQ(g.cluster_count(g.num_levels() - 1), 20u);
    EXPECT_EQ(c.cluster_count(c.num_levels() - 1), 20u);
    EXPECT_NEAR(g.energy(g.num_levels() - 1), c.energy(c.num_levels() - 1),
                0.01 * c.energy(c.num_levels() - 1));
  }
};

TEST_F(PointsPmlGpuTest, DeviceGpuRunsTheVoxelStartAndTheLevelsOnTheGlContext) {
  ExpectGpuLikeTheCpu("none");
}

// With LN k-means inside the levels (gpu/stages/points_optimise_gpu.h) too.
TEST_F(PointsPmlGpuTest, WithLnKmeansDeviceGpuRunsTheLevelsOnTheGlContext) {
  ExpectGpuLikeTheCpu("lnkmeans");
}

// With auto on llvmpipe the LN k-means levels stay on the CPU and say so.
TEST_F(PointsPmlGpuTest, WithLnKmeansAutoKeepsTheLevelsOnTheCpu) {
  std::vector<v1::Progress> progress;
  absl::StatusOr<client::JobResult> result = Run(Spec("auto", "lnkmeans"), &progress);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_EQ(ClusterDevice(progress), "cpu");
}

TEST_F(PointsPmlGpuTest, InjectedGlFailureIsACleanJobErrorAndTheServerKeepsServing) {
  for (const char* pass : {"voxel start", "points odes", "points neighbours"}) {
    ExpectFailsInPass(Spec("gpu", "none"), pass);
  }
  for (const char* pass : {"ln-kmeans assign", "points update"}) {
    ExpectFailsInPass(Spec("gpu", "lnkmeans"), pass);
  }
  ExpectRunsWithTheHookCleared(Spec("gpu", "none"));
  ExpectRunsWithTheHookCleared(Spec("gpu", "lnkmeans"));
}

}  // namespace
}  // namespace mlclust
