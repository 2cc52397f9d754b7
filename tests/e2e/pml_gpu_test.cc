// End-to-end: PML's levels on the GPU through the server (llvmpipe where there is no GPU).
// --device gpu --algo pml with optimizer none runs the levels on the GL context
// (gpu/stages/multilevel_gpu.h), names the renderer in the cluster stage's events and in
// Done, and streams the CPU's levels; with optimizer bb (Alg. 5.7) the levels and their BB
// sweeps run there too; with EMLO (not on the GPU) the cluster stage stays on the CPU and
// says so; a GL failure injected into a PML pass is a clean job error and the server keeps
// serving. --algo ml with optimizer bb (Alg. 5.6: one collapse, then BB sweeps, per level)
// runs on the GL context too, with device gpu.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <optional>
#include <string>
#include <vector>

#include "client/client.h"
#include "core/io/draco_codec.h"
#include "core/io/mesh_io.h"
#include "mlclust/v1/mlclust.grpc.pb.h"
#include "server/server.h"
#include "tests/fixtures/level_checks.h"
#include "tests/fixtures/test_meshes.h"
#include "tests/fixtures/test_server.h"

namespace mlclust {
namespace {

class PmlGpuTest : public testing::GpuServerTest {
 protected:
  static v1::JobSpec PmlSpec(const std::string& device, const std::string& optimizer) {
    v1::JobSpec spec = testing::MeshSpec(v1::ALGORITHM_PML, 20);
    spec.set_device(device);
    (*spec.mutable_options())["optimizer"] = optimizer;
    (*spec.mutable_options())["pml-pairs"] = "all";
    return spec;
  }
};

TEST_F(PmlGpuTest, DeviceGpuRunsThePmlLevelsOnTheGlContext) {
  std::optional<client::JobResult> gpu, cpu;
  ASSERT_NO_FATAL_FAILURE(RunOnGpuAndCpu(PmlSpec("gpu", "none"), PmlSpec("cpu", "none"), gpu, cpu));
  // The same levels: counts, energies within 1%, labels at every level.
  ASSERT_GT(gpu->hierarchy.num_levels(), 10u);
  testing::ExpectSameLevels(gpu->hierarchy, cpu->hierarchy, /*relative=*/0.01);
  EXPECT_EQ(gpu->hierarchy.cluster_count(gpu->hierarchy.num_levels() - 1), 20u);
}

// The GPU has no EMLO for PML: with EMLO the levels stay on the CPU (chosen at plan time
// and named in the events), even with device gpu.
TEST_F(PmlGpuTest, WithAnOptimiserTheLevelsStayOnTheCpu) {
  std::vector<v1::Progress> progress;
  absl::StatusOr<client::JobResult> result = Run(PmlSpec("gpu", "emlo"), &progress);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_EQ(ClusterDevice(progress), "cpu");
}

TEST_F(PmlGpuTest, InjectedGlFailureIsACleanJobErrorAndTheServerKeepsServing) {
  for (const char* pass : {"pml odes", "pml triplets"})
    ExpectFailsInPass(PmlSpec("gpu", "none"), pass);
  ExpectRunsWithTheHookCleared(PmlSpec("gpu", "none"));
}

// Alg. 5.7: with optimizer bb the levels and their BB sweeps run on the GL context (named
// in the events and Done); every level replays from the triplets, ends at the asked count,
// and the last level's energy is near the CPU engine's PML with BB (whose sweeps differ).
TEST_F(PmlGpuTest, OptimizerBbRunsOnTheGlContext) {
  std::optional<client::JobResult> gpu, cpu;
  ASSERT_NO_FATAL_FAILURE(RunOnGpuAndCpu(PmlSpec("gpu", "bb"), PmlSpec("cpu", "bb"), gpu, cpu));
  const size_t levels = gpu->hierarchy.num_levels();
  ASSERT_GT(levels, 10u);
  std::vector<ClusterId> labels(gpu->hierarchy.start_labels().begin(),
                                gpu->hierarchy.start_labels().end());
  for (size_t l = 1; l < levels; ++l) {
    ASSERT_TRUE(gpu->hierarchy.StepLabels(labels, l - 1, l).ok()) << "level " << l;
    EXPECT_LT(gpu->hierarchy.cluster_count(l), gpu->hierarchy.cluster_count(l - 1));
  }
  EXPECT_EQ(gpu->hierarchy.cluster_count(levels - 1), 20u);
  const size_t cpu_last = cpu->hierarchy.num_levels() - 1;
  EXPECT_EQ(cpu->hierarchy.cluster_count(cpu_last), 20u);
  EXPECT_NEAR(gpu->hierarchy.energy(levels - 1), cpu->hierarchy.energy(cpu_last),
              0.05 * cpu->hierarchy.energy(cpu_last));
}

TEST_F(PmlGpuTest, InjectedGlFailureInABbPassIsACleanJobError) {
  for (const char* pass : {"pml bb decide", "pml bb apply", "pml bb edges"}) {
    ExpectFailsInPass(PmlSpec("gpu", "bb"), pass);
  }
  ExpectRunsWithTheHookCleared(PmlSpec("gpu", "bb"));
}

// Alg. 5.6: --algo ml --optimizer bb --device gpu runs the steps and their BB sweeps on
// the GL context (named in the events and Done): one merge per level, every level replays
// from the triplets, and the energy at each count is at most 1% above the CPU engine's ML
// with BB. Fandisk (12,946 faces) down to 12,500 clusters (446 steps: every step sweeps every
// face).
TEST_F(PmlGpuTest, MlWithBbRunsOnTheGlContext) {
  auto ml_spec = [](const std::string& device) {
    v1::JobSpec spec = testing::MeshSpec(v1::ALGORITHM_ML, 12500);
    spec.set_device(device);
    (*spec.mutable_options())["optimizer"] = "bb";
    return spec;
  };
  std::optional<client::JobResult> gpu, cpu;
  ASSERT_NO_FATAL_FAILURE(RunOnGpuAndCpu(ml_spec("gpu"), ml_spec("cpu"), gpu, cpu));
  const HierarchyLog& log = gpu->hierarchy;
  ASSERT_EQ(log.num_levels(), cpu->hierarchy.num_levels());
  std::vector<ClusterId> labels(log.start_labels().begin(), log.start_labels().end());
  for (size_t l = 1; l < log.num_levels(); ++l) {
    ASSERT_TRUE(log.StepLabels(labels, l - 1, l).ok()) << "level " << l;
    EXPECT_EQ(log.cluster_count(l), log.cluster_count(l - 1) - 1);
    EXPECT_EQ(log.cluster_count(l), cpu->hierarchy.cluster_count(l));
    EXPECT_LE(log.energy(l), 1.01 * cpu->hierarchy.energy(l)) << "level " << l;
  }
  EXPECT_EQ(log.cluster_count(log.num_levels() - 1), 12500u);
  ExpectFailsInPass(ml_spec("gpu"), "ml min ode");
  ExpectRunsWithTheHookCleared(ml_spec("gpu"));
}

}  // namespace
}  // namespace mlclust
