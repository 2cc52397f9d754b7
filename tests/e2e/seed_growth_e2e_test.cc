// The seeding stage's growth on the GPU through the server (llvmpipe where there is no
// GPU): with --device gpu and growth rounds (section 5.2) the seed stage's events name
// the renderer and the seeding equals the CPU's (BB's preset patches, which grows
// energy-free, likewise); a GL failure injected into the pass
// "initial growth" is a clean job error.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "client/client.h"
#include "mlclust/v1/mlclust.grpc.pb.h"
#include "server/server.h"
#include "tests/fixtures/test_server.h"

namespace mlclust {
namespace {

class SeedGrowthGpuTest : public testing::GpuServerTest {
 protected:
  static v1::JobSpec Spec(v1::Algorithm algorithm, const std::string& device,
                          const std::string& growth = "rounds") {
    v1::JobSpec spec = testing::MeshSpec(algorithm, 100);
    spec.set_device(device);
    (*spec.mutable_options())["growth"] = growth;
    return spec;
  }
  // The device the seed stage's events name ("none" without one).
  static std::string SeedDevice(const std::vector<v1::Progress>& progress) {
    std::string device = "none";
    for (const v1::Progress& p : progress) {
      if (p.stage() == "seed") device = p.device();
    }
    return device;
  }
};

TEST_F(SeedGrowthGpuTest, EmloWithGrowthRoundsSeedsOnTheGpuAndEqualsTheCpu) {
  const std::string renderer = server_->gl_renderer();
  ASSERT_FALSE(renderer.empty());
  std::vector<v1::Progress> progress;
  absl::StatusOr<client::JobResult> gpu = Run(Spec(v1::ALGORITHM_EMLO, "gpu"), &progress);
  ASSERT_TRUE(gpu.ok()) << gpu.status();
  EXPECT_EQ(SeedDevice(progress), renderer);
  EXPECT_EQ(gpu->done.device(), renderer);
  progress.clear();
  absl::StatusOr<client::JobResult> cpu = Run(Spec(v1::ALGORITHM_EMLO, "cpu"), &progress);
  ASSERT_TRUE(cpu.ok()) << cpu.status();
  EXPECT_EQ(SeedDevice(progress), "cpu");
  // The seeding on the GPU is the CPU's to the bit, so EMLO (on the CPU) is too; and growth
  // rounds is growth free's partition.
  testing::ExpectSameHierarchy(gpu->hierarchy, cpu->hierarchy);
  absl::StatusOr<client::JobResult> free = Run(Spec(v1::ALGORITHM_EMLO, "cpu", "free"));
  ASSERT_TRUE(free.ok()) << free.status();
  testing::ExpectSameHierarchy(free->hierarchy, cpu->hierarchy);
}

TEST_F(SeedGrowthGpuTest, BbWithGrowthRoundsSeedsOnTheGpu) {
  const std::string renderer = server_->gl_renderer();
  std::vector<v1::Progress> progress;
  absl::StatusOr<client::JobResult> gpu = Run(Spec(v1::ALGORITHM_BB, "gpu"), &progress);
  ASSERT_TRUE(gpu.ok()) << gpu.status();
  EXPECT_EQ(SeedDevice(progress), renderer);
  absl::StatusOr<client::JobResult> cpu = Run(Spec(v1::ALGORITHM_BB, "cpu"));
  ASSERT_TRUE(cpu.ok()) << cpu.status();
  ASSERT_EQ(gpu->hierarchy.num_levels(), 2u);
  ASSERT_EQ(cpu->hierarchy.num_levels(), 2u);
  EXPECT_EQ(gpu->hierarchy.energy(0), cpu->hierarchy.energy(0));
  EXPECT_EQ(*gpu->hierarchy.LabelsAt(0), *cpu->hierarchy.LabelsAt(0));
  // The default growth (the flood) keeps the seed stage on the CPU.
  progress.clear();
  ASSERT_TRUE(Run(Spec(v1::ALGORITHM_BB, "gpu", "flood"), &progress).ok());
  EXPECT_EQ(SeedDevice(progress), "cpu");
}

// BB's preset patches grows energy-free, growth rounds' partition: with --device gpu and
// growth rounds its growth runs on the GPU, and the patches (swept on the CPU) equal the
// CPU run's.
TEST_F(SeedGrowthGpuTest, PresetPatchesGrowsOnTheGpuAndEqualsTheCpu) {
  auto spec = [](const std::string& device) {
    v1::JobSpec patches = testing::MeshSpec(v1::ALGORITHM_BB, 100);
    patches.set_device(device);
    (*patches.mutable_options())["preset"] = "patches";
    (*patches.mutable_options())["growth"] = "rounds";
    return patches;
  };
  std::vector<v1::Progress> progress;
  absl::StatusOr<client::JobResult> gpu = Run(spec("gpu"), &progress);
  ASSERT_TRUE(gpu.ok()) << gpu.status();
  EXPECT_EQ(SeedDevice(progress), server_->gl_renderer());
  progress.clear();
  absl::StatusOr<client::JobResult> cpu = Run(spec("cpu"), &progress);
  ASSERT_TRUE(cpu.ok()) << cpu.status();
  EXPECT_EQ(SeedDevice(progress), "cpu");
  testing::ExpectSameHierarchy(gpu->hierarchy, cpu->hierarchy);
  ExpectFailsInPass(spec("gpu"), "initial growth");
}

TEST_F(SeedGrowthGpuTest, InjectedGlFailureIsACleanJobError) {
  ExpectFailsInPass(Spec(v1::ALGORITHM_EMLO, "gpu"), "initial growth");
  ExpectRunsWithTheHookCleared(Spec(v1::ALGORITHM_EMLO, "gpu"));
}

}  // namespace
}  // namespace mlclust
