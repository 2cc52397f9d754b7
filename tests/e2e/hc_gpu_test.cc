// End-to-end: HC's steps on the GPU through the server (llvmpipe where there is no GPU).
// --device gpu --algo hc with cvd runs the steps on the GL context
// (gpu/stages/hierarchy_gpu.h), names the renderer in the cluster stage's events and in
// Done, and streams the CPU's levels exactly; with planar (no GPU merge cost) the cluster
// stage stays on the CPU and says so; a GL failure injected into an HC pass is a clean job
// error and the server keeps serving.
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

class HcGpuTest : public testing::GpuServerTest {
 protected:
  static v1::JobSpec HcSpec(const std::string& device, v1::Energy energy = v1::ENERGY_CVD) {
    v1::JobSpec spec = testing::MeshSpec(v1::ALGORITHM_HC, 20);
    spec.set_energy(energy);
    spec.set_device(device);
    return spec;
  }
};

TEST_F(HcGpuTest, DeviceGpuRunsTheHcStepsOnTheGlContext) {
  std::optional<client::JobResult> gpu, cpu;
  ASSERT_NO_FATAL_FAILURE(RunOnGpuAndCpu(HcSpec("gpu"), HcSpec("cpu"), gpu, cpu));
  // The same levels: counts, energies and labels at every level.
  ASSERT_GT(gpu->hierarchy.num_levels(), 10000u);
  testing::ExpectSameLevels(gpu->hierarchy, cpu->hierarchy, /*relative=*/0);
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
    ExpectFailsInPass(HcSpec("gpu"), pass);
  }
  ExpectRunsWithTheHookCleared(HcSpec("gpu"));
}

}  // namespace
}  // namespace mlclust
