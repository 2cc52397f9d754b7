// End-to-end: PML for points on the GPU through the server (llvmpipe where there is no
// GPU). --device gpu --algo pml --optimizer none runs the voxel start and the levels on
// the GL context (gpu/stages/points_multilevel_gpu.h) and names the renderer in the
// cluster stage's events and in Done; the start is the CPU's; with LN k-means
// (gpu/stages/points_optimise_gpu.h) device gpu runs the levels on the GPU too and auto
// on llvmpipe keeps them on the CPU; a GL failure injected into a pass is a clean job
// error and the server keeps serving. HC and ML (one merge per level, RunPointHierarchyGpu)
// with --device gpu as well.
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

  static v1::JobSpec Spec(const std::string& device, const std::string& optimizer,
                          v1::Algorithm algorithm = v1::ALGORITHM_PML) {
    v1::JobSpec spec;
    spec.set_input_kind(v1::INPUT_KIND_POINTS_F32);
    spec.set_point_dims(3);
    spec.set_algorithm(algorithm);
    spec.set_clusters(20);
    spec.set_device(device);
    if (!optimizer.empty()) (*spec.mutable_options())["optimizer"] = optimizer;
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

// HC (merges only) and ML (LN k-means around each merge) with --device gpu: the steps on
// the GL context (named in the events), HC's levels the CPU's (every level's count and
// energy), ML's lowest level within 1% of the CPU's; auto keeps both on the CPU; a GL
// failure injected into the steps' passes is a clean job error.
TEST_F(PointsPmlGpuTest, HcAndMlDeviceGpuRunTheStepsOnTheGlContext) {
  std::optional<client::JobResult> gpu, cpu;
  ASSERT_NO_FATAL_FAILURE(RunOnGpuAndCpu(Spec("gpu", "", v1::ALGORITHM_HC),
                                         Spec("cpu", "", v1::ALGORITHM_HC), gpu, cpu));
  ASSERT_GT(cpu->hierarchy.num_levels(), 50u);
  ASSERT_EQ(gpu->hierarchy.num_levels(), cpu->hierarchy.num_levels());
  for (size_t l = 0; l < cpu->hierarchy.num_levels(); ++l) {
    EXPECT_EQ(gpu->hierarchy.cluster_count(l), cpu->hierarchy.cluster_count(l)) << l;
    EXPECT_NEAR(gpu->hierarchy.energy(l), cpu->hierarchy.energy(l), 1e-9 * cpu->hierarchy.energy(l))
        << l;
  }
  gpu.reset();
  cpu.reset();
  ASSERT_NO_FATAL_FAILURE(RunOnGpuAndCpu(Spec("gpu", "lnkmeans", v1::ALGORITHM_ML),
                                         Spec("cpu", "lnkmeans", v1::ALGORITHM_ML), gpu, cpu));
  const auto& g = gpu->hierarchy;
  const auto& c = cpu->hierarchy;
  EXPECT_EQ(g.cluster_count(g.num_levels() - 1), 20u);
  EXPECT_NEAR(g.energy(g.num_levels() - 1), c.energy(c.num_levels() - 1),
              0.01 * c.energy(c.num_levels() - 1));
  for (const v1::Algorithm algorithm : {v1::ALGORITHM_HC, v1::ALGORITHM_ML}) {
    std::vector<v1::Progress> progress;
    absl::StatusOr<client::JobResult> result =
        Run(Spec("auto", algorithm == v1::ALGORITHM_ML ? "lnkmeans" : "", algorithm), &progress);
    ASSERT_TRUE(result.ok()) << result.status();
    EXPECT_EQ(ClusterDevice(progress), "cpu");
  }
  ExpectFailsInPass(Spec("gpu", "", v1::ALGORITHM_HC), "points hc select");
  ExpectFailsInPass(Spec("gpu", "lnkmeans", v1::ALGORITHM_ML), "points hc neighbours");
  ExpectRunsWithTheHookCleared(Spec("gpu", "lnkmeans", v1::ALGORITHM_ML));
}

}  // namespace
}  // namespace mlclust
