// Every algorithm x device x input kind x machine through the server's plan (PlanJobOnDevice,
// as at submit), its lane (device_policy.h LaneFor, for 0 and 2 CPU workers) and the runner,
// on a stand-in GPU whose stages are the CPU's (so it runs anywhere) and count their calls:
// each stage runs where the plan says, its Progress names that device, and Done.devices
// names each stage's device as it ran (issue 23's (a), (b) and (c)).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "core/cluster/device_stages.h"
#include "core/cluster/kmeans.h"
#include "core/cluster/mesh_clustering.h"
#include "core/cluster/multilevel.h"
#include "core/cluster/point_clustering.h"
#include "core/cluster/registry.h"
#include "core/mesh/face_measures.h"
#include "core/plan/device_policy.h"
#include "server/job_runner.h"
#include "tests/fixtures/job_runs.h"

namespace mlclust {
namespace {

using ::testing::HasSubstr;

// The GPU stages' contract run by the CPU's drivers; counts which were called.
class StandInGpu : public DeviceStages {
 public:
  absl::StatusOr<FaceMeasures> MeasureFaces(const TriangleMesh& mesh) override {
    ++calls["measures"];
    return ComputeFaceMeasures(mesh);
  }
  absl::StatusOr<OptimizeResult> OptimizeBoundaryBased(
      const MeshProblem& problem, std::vector<ClusterId>& labels,
      const BoundaryBasedOptions& options) override {
    ++calls["cluster"];
    return ::mlclust::OptimizeBoundaryBased(problem, labels, options);
  }
  absl::StatusOr<LnKmeansResult> RunLnKmeans(const PointSet& points, std::vector<ClusterId> labels,
                                             const LnKmeansOptions& options) override {
    ++calls["cluster"];
    return ::mlclust::RunLnKmeans(points, std::move(labels), options);
  }
  absl::StatusOr<KmeansResult> RunLloyd(const PointSet& points, std::vector<float> centres,
                                        const KmeansOptions& options) override {
    ++calls["cluster"];
    return ::mlclust::RunLloyd(points, std::move(centres), options);
  }
  absl::StatusOr<MultilevelSummary> RunMultilevel(const MeshProblem& problem,
                                                  const MultilevelOptions& options,
                                                  LevelSink& sink) override {
    ++calls["cluster"];
    return ::mlclust::RunMultilevel(problem, options, sink);
  }
  absl::StatusOr<MultilevelSummary> RunHierarchy(const MeshProblem& problem,
                                                 const MultilevelOptions& options,
                                                 LevelSink& sink) override {
    ++calls["cluster"];
    return ::mlclust::RunMultilevel(problem, options, sink);
  }
  absl::StatusOr<PointMultilevelSummary> RunPointMultilevel(const PointSet& points,
                                                            const PointMultilevelOptions& options,
                                                            LevelSink& sink) override {
    ++calls["cluster"];
    return ::mlclust::RunPointMultilevel(points, options, sink);
  }
  SeedOptions::DeviceGrowth RoundsGrowth() override {
    ++calls["seed"];
    return {};  // the default plans do not grow in rounds
  }

  std::map<std::string, int> calls;
};

// `m` points in `d` dimensions on four well-apart blobs (deterministic), as the wire's bytes.
std::string PointBytes(uint32_t m, uint32_t d) {
  std::vector<float> values(size_t{m} * d);
  for (uint32_t i = 0; i < m; ++i) {
    for (uint32_t j = 0; j < d; ++j) {
      values[size_t{i} * d + j] =
          static_cast<float>(10 * ((i % 4) == j % 4) + 0.01 * ((i * 7 + j * 13) % 97));
    }
  }
  return std::string(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(float));
}

v1::JobSpec SpecFor(const AlgorithmInfo& algorithm, const std::string& device, uint32_t dims,
                    const std::string& input) {
  v1::JobSpec spec;
  spec.set_algorithm(static_cast<v1::Algorithm>(algorithm.wire));
  spec.set_device(device);
  spec.set_clusters(algorithm.hierarchy && !algorithm.divisive ? 0 : 6);
  spec.set_input_bytes(input.size());
  if (algorithm.input == InputKind::kMesh) {
    spec.set_input_kind(v1::INPUT_KIND_DRACO_MESH);
    if (algorithm.name == "vsa") spec.set_energy(v1::ENERGY_PLANAR);
  } else {
    spec.set_input_kind(v1::INPUT_KIND_POINTS_F32);
    spec.set_point_dims(dims);
  }
  return spec;
}

struct Ran {
  absl::StatusOr<server::JobOutcome> outcome;
  std::vector<v1::Progress> progress;
  std::map<std::string, int> gpu_calls;
};

// The job as the server runs it: planned at submit, run by the worker of its lane (the GL
// worker's has the GPU stages, a CPU worker's none).
Ran RunOnLane(const v1::JobSpec& spec, const std::string& input, const JobPlan& plan,
              const DeviceCaps& caps, server::JobLane lane) {
  auto channel = std::make_shared<testing::KeepingChannel>();
  StandInGpu gpu;
  server::Job job;
  job.spec = spec;
  job.input = input;
  job.events = channel;
  job.plan = plan;
  server::JobRunnerContext context;
  context.device = caps;
  if (lane == server::JobLane::kGl) context.devices = &gpu;
  Ran ran{server::RunJob(job, context), {}, {}};
  for (const v1::JobEvent& event : channel->events) {
    if (event.has_progress()) ran.progress.push_back(event.progress());
  }
  ran.gpu_calls = gpu.calls;
  return ran;
}

std::map<std::string, std::string> DoneDevices(const v1::Done& done) {
  std::map<std::string, std::string> devices;
  for (const v1::StageRan& stage : done.devices()) {
    EXPECT_TRUE(devices.emplace(stage.stage(), stage.device()).second) << stage.stage();
  }
  return devices;
}

TEST(DeviceRunsTest, EveryStageRunsAndIsReportedWhereThePlanPutsIt) {
  const std::string mesh = testing::CubeDraco();
  const std::string points = PointBytes(240, 3);
  const DeviceCaps software{true, true, "llvmpipe (stand-in)"};
  const DeviceCaps hardware{true, false, "NVIDIA (stand-in)"};
  int runs = 0;
  for (const AlgorithmInfo& algorithm : Algorithms()) {
    const std::string& input = algorithm.input == InputKind::kMesh ? mesh : points;
    for (const char* device : {"cpu", "auto", "gpu"}) {
      for (const DeviceCaps* caps : {&software, &hardware}) {
        const std::string what = absl::StrCat(InputKindName(algorithm.input), " ", algorithm.name,
                                              " --device ", device, " on ", caps->renderer);
        const v1::JobSpec spec = SpecFor(algorithm, device, 3, input);
        absl::StatusOr<JobPlan> plan = server::PlanJobOnDevice(spec, *caps);
        if (!plan.ok()) {
          // Only device gpu for an algorithm without any GPU stage.
          EXPECT_EQ(std::string(device), "gpu") << what << ": " << plan.status();
          EXPECT_THAT(plan.status().message(), HasSubstr("has a GPU implementation yet")) << what;
          continue;
        }
        // The lane is the plan's, with CPU workers or without.
        const server::JobLane lane =
            LaneFor(*plan, /*has_cpu_workers=*/true, false) == WorkerLane::kGl
                ? server::JobLane::kGl
                : server::JobLane::kCpu;
        EXPECT_EQ(lane == server::JobLane::kGl, UsesGpu(*plan)) << what;
        EXPECT_EQ(LaneFor(*plan, /*has_cpu_workers=*/false, false), WorkerLane::kGl) << what;

        const Ran ran = RunOnLane(spec, input, *plan, *caps, lane);
        ASSERT_TRUE(ran.outcome.ok()) << what << ": " << ran.outcome.status();
        const v1::Done& done = ran.outcome->done;
        const std::map<std::string, std::string> devices = DoneDevices(done);
        // Every stage Done names is one of the plan's, on the plan's device; the cluster
        // stage (and a mesh's measures) always run.
        EXPECT_TRUE(devices.contains("cluster")) << what;
        if (algorithm.input == InputKind::kMesh) {
          EXPECT_TRUE(devices.contains("measures")) << what;
        }
        bool any_gpu = false;
        for (const auto& [stage, ran_on] : devices) {
          const StagePlan* planned = FindStage(*plan, stage);
          ASSERT_NE(planned, nullptr) << what << ": " << stage;
          EXPECT_EQ(ran_on, StageDeviceName(*planned, *caps)) << what << ": " << stage;
          // What ran on the GPU called the GPU's stage; what ran on the CPU did not.
          const auto calls = ran.gpu_calls.find(stage);
          const bool called = calls != ran.gpu_calls.end() && calls->second > 0;
          EXPECT_EQ(called, planned->device == StageDevice::kGpu) << what << ": " << stage;
          any_gpu |= planned->device == StageDevice::kGpu;
        }
        EXPECT_EQ(done.device(), any_gpu ? caps->renderer : "cpu") << what;
        // Every Progress of a stage names the device Done names for it.
        for (const v1::Progress& p : ran.progress) {
          if (devices.contains(p.stage())) {
            EXPECT_EQ(p.device(), devices.at(p.stage())) << what << ": " << p.message();
          }
        }
        // Device gpu: a stage on the CPU is said in a "plan" Progress, before any stage.
        const bool cpu_stage = std::any_of(plan->stages.begin(), plan->stages.end(),
                                           [](const StagePlan& s) { return !s.why.empty(); });
        const bool plan_said = !ran.progress.empty() && ran.progress.front().stage() == "plan";
        EXPECT_EQ(plan_said, cpu_stage) << what;
        ++runs;
      }
    }
  }
  EXPECT_EQ(runs, 13 * 3 * 2 - 2 * 2);  // less gpu for X-means and bisecting on both
}

TEST(DeviceRunsTest, PointsOverTheGpusDimensionsRunOnTheCpuAndSaySoInDone) {
  // Issue 23's (b): a run-time override moved such a set to the CPU while Done named the
  // GPU. Now the plan decides, at submit, from the spec's point_dims.
  const DeviceCaps hardware{true, false, "NVIDIA (stand-in)"};
  const std::string points = PointBytes(120, kGpuPointMaxDims + 1);
  v1::JobSpec spec =
      SpecFor(*FindAlgorithm(InputKind::kPoints, "pml"), "auto", kGpuPointMaxDims + 1, points);
  (*spec.mutable_options())["optimizer"] = "none";
  absl::StatusOr<JobPlan> plan = server::PlanJobOnDevice(spec, hardware);
  ASSERT_TRUE(plan.ok()) << plan.status();
  EXPECT_EQ(LaneFor(*plan, true, false), WorkerLane::kCpu);
  const Ran ran = RunOnLane(spec, points, *plan, hardware, server::JobLane::kCpu);
  ASSERT_TRUE(ran.outcome.ok()) << ran.outcome.status();
  EXPECT_EQ(ran.outcome->done.device(), "cpu");
  EXPECT_EQ(DoneDevices(ran.outcome->done),
            (std::map<std::string, std::string>{{"cluster", "cpu"}}));
  ASSERT_FALSE(ran.progress.empty());
  EXPECT_EQ(ran.progress.front().stage(), "plan");
  EXPECT_THAT(ran.progress.front().message(), HasSubstr("65 dimensions: over the GPU's 64"));
  // With 64 dimensions the same job is the GPU's.
  const std::string fits = PointBytes(120, kGpuPointMaxDims);
  spec.set_point_dims(kGpuPointMaxDims);
  spec.set_input_bytes(fits.size());
  plan = server::PlanJobOnDevice(spec, hardware);
  ASSERT_TRUE(plan.ok()) << plan.status();
  EXPECT_EQ(LaneFor(*plan, true, false), WorkerLane::kGl);
  // Device gpu over the limit is refused at plan time.
  spec.set_device("gpu");
  spec.set_point_dims(kGpuPointMaxDims + 1);
  spec.set_input_bytes(points.size());
  EXPECT_EQ(server::PlanJobOnDevice(spec, hardware).status().code(),
            absl::StatusCode::kFailedPrecondition);
}

TEST(DeviceRunsTest, AMeshOverTheFreeMemoryMovesToTheCpuOnceDecoded) {
  // A mesh's faces are known once decoded: the plan at submit puts the measures on the
  // GPU; the runner fits the plan to the mesh and, with auto, runs them on the CPU, saying
  // why; with gpu, refuses before any stage.
  DeviceCaps caps{true, false, "NVIDIA (stand-in)"};
  caps.free_bytes = 100;
  caps.gpu_working_set = [](PlanStage, const JobPlan&, const InputShape& input) {
    return input.elements;  // a byte per face: the cube's 192 faces do not fit in 100
  };
  const std::string mesh = testing::CubeDraco();
  v1::JobSpec spec = SpecFor(*FindAlgorithm(InputKind::kMesh, "ml"), "auto", 0, mesh);
  absl::StatusOr<JobPlan> plan = server::PlanJobOnDevice(spec, caps);
  ASSERT_TRUE(plan.ok()) << plan.status();
  ASSERT_EQ(LaneFor(*plan, true, false), WorkerLane::kGl);
  const Ran ran = RunOnLane(spec, mesh, *plan, caps, server::JobLane::kGl);
  ASSERT_TRUE(ran.outcome.ok()) << ran.outcome.status();
  EXPECT_EQ(DoneDevices(ran.outcome->done).at("measures"), "cpu");
  EXPECT_EQ(ran.gpu_calls.count("measures"), 0u);
  bool said = false;
  for (const v1::Progress& p : ran.progress) {
    said |= p.stage() == "plan" && absl::StrContains(p.message(), "measures on the CPU") &&
            absl::StrContains(p.message(), "over the device's free");
  }
  EXPECT_TRUE(said);

  spec.set_device("gpu");
  plan = server::PlanJobOnDevice(spec, caps);
  ASSERT_TRUE(plan.ok()) << plan.status();
  const Ran refused = RunOnLane(spec, mesh, *plan, caps, server::JobLane::kGl);
  EXPECT_EQ(refused.outcome.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(refused.outcome.status().message(), HasSubstr("the measures stage cannot run"));
  EXPECT_TRUE(refused.gpu_calls.empty());
}

}  // namespace
}  // namespace mlclust
