// The device policy (core/plan/device_policy.h): every algorithm x device choice x machine x
// worker count through the plan, against a table written out here; the device limits
// (memory, dimensions) with the device's free memory injected; the coverage rules.
#include "core/plan/device_policy.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <map>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/cluster/registry.h"

namespace mlclust {
namespace {

using ::testing::HasSubstr;

const DeviceCaps kNoGpu;
const DeviceCaps kSoftware{true, true, "llvmpipe"};
const DeviceCaps kHardware{true, false, "NVIDIA H100"};

JobPlan DefaultPlan(const AlgorithmInfo& algorithm, DeviceChoice device) {
  JobRequest request;
  request.algorithm = &algorithm;
  request.device = device;
  request.clusters = algorithm.hierarchy && !algorithm.divisive ? 0 : 10;
  absl::StatusOr<JobPlan> plan = PlanJob(request);
  EXPECT_TRUE(plan.ok()) << algorithm.name << ": " << plan.status();
  return plan.ok() ? *plan : JobPlan();
}

// The stages a job of `algorithm` with its default options runs on the GPU, written out
// (not read from the policy): "" for none. `gpu_only` are those device gpu takes but auto
// does not (latency-bound steps).
struct Expected {
  std::vector<std::string> stages;    // with auto on hardware and with gpu
  std::vector<std::string> gpu_only;  // with gpu only
  bool any_implementation = true;     // false: device gpu is refused
};

Expected ExpectedFor(const AlgorithmInfo& algorithm) {
  const std::string key = absl::StrCat(InputKindName(algorithm.input), ":", algorithm.name);
  static const auto* table = new std::map<std::string, Expected>{
      // Meshes: the measures everywhere; HC's steps gpu only; ML's and PML's default
      // optimiser (EMLO) and EMLO, VSA have no GPU cluster stage; BB's decide for cvd; the
      // seed grows on the GPU with growth rounds only (not the default).
      {"mesh:hc", {{"measures"}, {"cluster"}}},
      {"mesh:ml", {{"measures"}, {}}},
      {"mesh:pml", {{"measures"}, {}}},
      {"mesh:emlo", {{"measures"}, {}}},
      {"mesh:bb", {{"measures", "cluster"}, {}}},
      {"mesh:vsa", {{"measures"}, {}}},
      // Points: HC's and ML's steps and PML with LN k-means (its default) gpu only;
      // LN k-means and k-means on the GPU; X-means and bisecting k-means none.
      {"points:hc", {{}, {"cluster"}}},
      {"points:ml", {{}, {"cluster"}}},
      {"points:pml", {{}, {"cluster"}}},
      {"points:lnkmeans", {{"cluster"}, {}}},
      {"points:kmeans", {{"cluster"}, {}}},
      {"points:xmeans", {{}, {}, false}},
      {"points:bisecting", {{}, {}, false}},
  };
  auto found = table->find(key);
  EXPECT_NE(found, table->end()) << key << ": a new algorithm needs a row here";
  return found != table->end() ? found->second : Expected();
}

bool Contains(const std::vector<std::string>& names, const std::string& name) {
  return std::find(names.begin(), names.end(), name) != names.end();
}

TEST(DevicePolicyTest, EveryAlgorithmDeviceMachineAndWorkerCountGetsTheTablesStagesAndLane) {
  struct Machine {
    const char* name;
    const DeviceCaps* caps;
  };
  const Machine machines[] = {{"none", &kNoGpu}, {"llvmpipe", &kSoftware}, {"h100", &kHardware}};
  int planned = 0;
  for (const AlgorithmInfo& algorithm : Algorithms()) {
    const Expected expected = ExpectedFor(algorithm);
    for (DeviceChoice choice : {DeviceChoice::kCpu, DeviceChoice::kAuto, DeviceChoice::kGpu}) {
      for (const Machine& machine : machines) {
        const std::string what =
            absl::StrCat(InputKindName(algorithm.input), " ", algorithm.name, " device ",
                         static_cast<int>(choice), " on ", machine.name);
        JobPlan plan = DefaultPlan(algorithm, choice);
        const absl::Status status = PlanDevices(*machine.caps, plan);
        const bool gpu_asked = choice == DeviceChoice::kGpu;
        if (gpu_asked && (!machine.caps->gpu || !expected.any_implementation)) {
          EXPECT_EQ(status.code(), absl::StatusCode::kFailedPrecondition) << what;
          EXPECT_THAT(status.message(), HasSubstr("option device: 'gpu'")) << what;
          continue;
        }
        ASSERT_TRUE(status.ok()) << what << ": " << status;
        const bool gpu_taken =
            machine.caps->gpu &&
            (gpu_asked || (choice == DeviceChoice::kAuto && !machine.caps->gpu_is_software));
        // Each stage of the algorithm once, measures first for meshes.
        ASSERT_EQ(plan.stages.size(),
                  algorithm.stages.size() + (algorithm.input == InputKind::kMesh ? 1 : 0))
            << what;
        for (const StagePlan& stage : plan.stages) {
          const bool on_gpu =
              gpu_taken && (Contains(expected.stages, stage.name()) ||
                            (gpu_asked && Contains(expected.gpu_only, stage.name())));
          EXPECT_EQ(stage.device, on_gpu ? StageDevice::kGpu : StageDevice::kCpu)
              << what << ", stage " << stage.name();
          EXPECT_EQ(StageDeviceName(stage, *machine.caps),
                    on_gpu ? machine.caps->renderer : std::string("cpu"))
              << what;
          // Device gpu says why a stage stays on the CPU; auto and cpu say nothing.
          EXPECT_EQ(stage.why.empty(), !gpu_asked || on_gpu) << what << ", " << stage.name();
        }
        // The lane: the GL worker where a stage is on the GPU (or no CPU workers).
        for (bool workers : {false, true}) {
          for (bool preview : {false, true}) {
            const WorkerLane lane = LaneFor(plan, workers, preview);
            EXPECT_EQ(lane,
                      !workers || preview || UsesGpu(plan) ? WorkerLane::kGl : WorkerLane::kCpu)
                << what << ", workers " << workers << ", preview " << preview;
          }
        }
        // Bug (a) of issue 23: points with device gpu on a server with a GPU went to a CPU
        // worker and were refused there.
        if (algorithm.input == InputKind::kPoints && gpu_asked && UsesGpu(plan)) {
          EXPECT_EQ(LaneFor(plan, /*has_cpu_workers=*/true, false), WorkerLane::kGl) << what;
        }
        ++planned;
      }
    }
  }
  EXPECT_EQ(planned, 13 * 9 - 13 - 2 * 2);  // less gpu on none (13) and no GPU stage (2 x 2)
}

TEST(DevicePolicyTest, PointLevelsOverSixtyFourDimensionsAreRefusedWithGpuAndOnTheCpuWithAuto) {
  // Bug (b) of issue 23: the d > 64 rule was a run-time override the plan (and Done) did not
  // know; now it is the plan's.
  const AlgorithmInfo& pml = *FindAlgorithm(InputKind::kPoints, "pml");
  JobRequest request;
  request.algorithm = &pml;
  request.options = {{"optimizer", "none"}};  // auto's PML on the GPU: merges only
  InputShape shape;
  shape.elements = 1000;
  shape.dims = kGpuPointMaxDims;
  request.device = DeviceChoice::kAuto;
  JobPlan plan = *PlanJob(request);
  ASSERT_TRUE(PlanDevices(kHardware, shape, plan).ok());
  EXPECT_EQ(FindStage(plan, PlanStage::kCluster)->device, StageDevice::kGpu);

  shape.dims = kGpuPointMaxDims + 1;
  ASSERT_TRUE(PlanDevices(kHardware, shape, plan).ok());
  const StagePlan& cluster = *FindStage(plan, PlanStage::kCluster);
  EXPECT_EQ(cluster.device, StageDevice::kCpu);
  EXPECT_THAT(cluster.why, HasSubstr("65 dimensions: over the GPU's 64"));
  EXPECT_EQ(LaneFor(plan, true, false), WorkerLane::kCpu);

  request.device = DeviceChoice::kGpu;
  plan = *PlanJob(request);
  const absl::Status refused = PlanDevices(kHardware, shape, plan);
  EXPECT_EQ(refused.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(refused.message(), HasSubstr("65 dimensions"));

  // LN k-means' assignment has no such limit.
  request.algorithm = FindAlgorithm(InputKind::kPoints, "lnkmeans");
  request.options = {};
  request.clusters = 5;
  plan = *PlanJob(request);
  ASSERT_TRUE(PlanDevices(kHardware, shape, plan).ok());
  EXPECT_EQ(FindStage(plan, PlanStage::kCluster)->device, StageDevice::kGpu);
}

TEST(DevicePolicyTest, AWorkingSetOverTheFreeMemoryIsRefusedWithGpuAndOnTheCpuWithAuto) {
  DeviceCaps caps = kHardware;
  caps.free_bytes = 1000;
  std::vector<PlanStage> asked;
  caps.gpu_working_set = [&asked](PlanStage stage, const JobPlan&, const InputShape& input) {
    asked.push_back(stage);
    // The measures fit; BB's decide needs more than there is.
    return stage == PlanStage::kMeasures ? uint64_t{1000} : 10 * input.elements;
  };
  JobRequest request;
  request.algorithm = FindAlgorithm(InputKind::kMesh, "bb");
  request.clusters = 10;
  InputShape mesh;
  mesh.elements = 101;
  mesh.vertices = 60;

  request.device = DeviceChoice::kAuto;
  JobPlan plan = *PlanJob(request);
  ASSERT_TRUE(PlanDevices(caps, mesh, plan).ok());
  EXPECT_EQ(FindStage(plan, PlanStage::kMeasures)->device, StageDevice::kGpu);
  const StagePlan& cluster = *FindStage(plan, PlanStage::kCluster);
  EXPECT_EQ(cluster.device, StageDevice::kCpu);
  EXPECT_THAT(cluster.why, HasSubstr("working set of 0 MiB (1010 bytes) is over the device's "
                                     "free 0 MiB (1000 bytes)"));
  EXPECT_EQ(asked, (std::vector<PlanStage>{PlanStage::kMeasures, PlanStage::kCluster}));

  request.device = DeviceChoice::kGpu;
  plan = *PlanJob(request);
  const absl::Status refused = PlanDevices(caps, mesh, plan);
  EXPECT_EQ(refused.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(refused.message(), HasSubstr("the cluster stage cannot run on NVIDIA H100"));

  // A mesh whose faces are not known yet (at submit) is not checked; once they are,
  // FitDevicesToInput checks, and only ever moves a stage to the CPU.
  plan = *PlanJob(request);
  ASSERT_TRUE(PlanDevices(caps, InputShape(), plan).ok());
  EXPECT_EQ(FindStage(plan, PlanStage::kCluster)->device, StageDevice::kGpu);
  EXPECT_EQ(FitDevicesToInput(caps, mesh, plan).code(), absl::StatusCode::kFailedPrecondition);
  mesh.elements = 99;
  EXPECT_TRUE(FitDevicesToInput(caps, mesh, plan).ok());
  EXPECT_EQ(FindStage(plan, PlanStage::kCluster)->device, StageDevice::kGpu);

  // A driver that reports no free memory (llvmpipe): nothing is checked.
  caps.free_bytes.reset();
  mesh.elements = 1 << 20;
  plan = *PlanJob(request);
  ASSERT_TRUE(PlanDevices(caps, mesh, plan).ok());
  EXPECT_EQ(FindStage(plan, PlanStage::kCluster)->device, StageDevice::kGpu);
}

TEST(DevicePolicyTest, DeviceGpuSaysWhyAStageTheGpuDoesNotCoverRunsOnTheCpu) {
  // Issue 23's (c): PML with its default optimiser (EMLO) has only its measures on the GPU.
  JobRequest request;
  request.algorithm = FindAlgorithm(InputKind::kMesh, "pml");
  request.device = DeviceChoice::kGpu;
  JobPlan plan = *PlanJob(request);
  ASSERT_TRUE(PlanDevices(kSoftware, plan).ok());
  EXPECT_EQ(FindStage(plan, PlanStage::kMeasures)->device, StageDevice::kGpu);
  EXPECT_EQ(FindStage(plan, PlanStage::kCluster)->device, StageDevice::kCpu);
  EXPECT_THAT(FindStage(plan, PlanStage::kCluster)->why, HasSubstr("not EMLO"));
  request.options = {{"optimizer", "none"}};
  plan = *PlanJob(request);
  ASSERT_TRUE(PlanDevices(kSoftware, plan).ok());
  EXPECT_EQ(FindStage(plan, PlanStage::kCluster)->device, StageDevice::kGpu);
  // EMLO has no GPU cluster stage at all.
  request.algorithm = FindAlgorithm(InputKind::kMesh, "emlo");
  request.options = {};
  request.clusters = 5;
  plan = *PlanJob(request);
  ASSERT_TRUE(PlanDevices(kSoftware, plan).ok());
  EXPECT_EQ(FindStage(plan, PlanStage::kCluster)->why,
            "emlo's cluster stage has no GPU implementation");
  // Per-polygon jobs run on the CPU.
  InputShape polygons;
  polygons.polygons = true;
  request.device = DeviceChoice::kAuto;
  plan = *PlanJob(request);
  ASSERT_TRUE(PlanDevices(kHardware, polygons, plan).ok());
  EXPECT_FALSE(UsesGpu(plan));
  request.device = DeviceChoice::kGpu;
  plan = *PlanJob(request);
  EXPECT_EQ(PlanDevices(kHardware, polygons, plan).code(), absl::StatusCode::kFailedPrecondition);
}

TEST(DevicePolicyTest, ThePointsOptimisedGridStartRunsTheLevelsOnTheCpuAndSaysWhy) {
  // Issue 26 item 3's start (LN k-means on the voxel clusters first) has no GPU path: HC, ML
  // and PML keep their levels on the CPU with device gpu, and the plan says why.
  for (const char* name : {"hc", "ml", "pml"}) {
    JobRequest request;
    request.algorithm = FindAlgorithm(InputKind::kPoints, name);
    request.device = DeviceChoice::kGpu;
    request.options = {{"start", "optimised-grid"}};
    if (std::string(name) == "pml") request.options.push_back({"optimizer", "none"});
    JobPlan plan = *PlanJob(request);
    ASSERT_TRUE(PlanDevices(kSoftware, plan).ok()) << name;
    EXPECT_EQ(FindStage(plan, PlanStage::kCluster)->device, StageDevice::kCpu) << name;
    EXPECT_THAT(FindStage(plan, PlanStage::kCluster)->why, HasSubstr("optimised-grid")) << name;
    request.options[0].second = "grid";
    plan = *PlanJob(request);
    ASSERT_TRUE(PlanDevices(kSoftware, plan).ok()) << name;
    EXPECT_EQ(FindStage(plan, PlanStage::kCluster)->device, StageDevice::kGpu) << name;
  }
}

TEST(DevicePolicyTest, StageHasGpuAndMayUseGpu) {
  EXPECT_TRUE(StageHasGpu(*FindAlgorithm(InputKind::kMesh, "vsa"), PlanStage::kMeasures));
  EXPECT_FALSE(StageHasGpu(*FindAlgorithm(InputKind::kMesh, "vsa"), PlanStage::kSeed));
  EXPECT_TRUE(StageHasGpu(*FindAlgorithm(InputKind::kMesh, "emlo"), PlanStage::kSeed));
  EXPECT_FALSE(StageHasGpu(*FindAlgorithm(InputKind::kMesh, "emlo"), PlanStage::kCluster));
  EXPECT_FALSE(StageHasGpu(*FindAlgorithm(InputKind::kPoints, "xmeans"), PlanStage::kCluster));
  EXPECT_TRUE(StageHasGpu(*FindAlgorithm(InputKind::kPoints, "hc"), PlanStage::kCluster));
  EXPECT_FALSE(MayUseGpu(DeviceChoice::kCpu, true));
  EXPECT_FALSE(MayUseGpu(DeviceChoice::kAuto, false));
  EXPECT_TRUE(MayUseGpu(DeviceChoice::kAuto, true));
  EXPECT_TRUE(MayUseGpu(DeviceChoice::kGpu, false));
}

}  // namespace
}  // namespace mlclust
