// PML for meshes on the GPU (gpu/stages/multilevel_gpu.h, gpu/kernels/pml_levels.h)
// against the CPU engine's PML (core/cluster/multilevel.h, merges only), on llvmpipe.
#include "gpu/stages/multilevel_gpu.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cstdlib>
#include <tuple>

#include "core/cluster/multilevel.h"
#include "core/cluster/registry.h"
#include "gpu/context/gl_context.h"
#include "gpu/context/pass.h"
#include "gpu/kernels/pml_levels.h"
#include "gpu/tools/test_meshes.h"
#include "tests/fixtures/gl_test_context.h"
#include "tests/fixtures/level_checks.h"
#include "tests/fixtures/recording_sink.h"
#include "tests/fixtures/test_meshes.h"

namespace mlclust::gpu {
namespace {

using ::testing::HasSubstr;
namespace fixtures = ::mlclust::testing;
namespace meshes = ::mlclust::gpu::testing;

GlContext& Context() { return ::mlclust::testing::SharedGlContext(); }

// Every level: its count, energy and triplets (sorted: the CPU reports them in merge
// order, the GPU in face order).
struct LevelsSink : fixtures::TripletSink {
  LevelsSink() : TripletSink(/*sorted=*/true) {}
};

MultilevelOptions PmlOptions(PmlPairRule rule, uint32_t lowest) {
  MultilevelOptions options;
  options.parallel = true;
  options.optimizer = MultilevelOptions::Optimizer::kNone;
  options.pml_pairs = rule;
  options.min_clusters = lowest;
  return options;
}

// The GPU's levels against the CPU's: the same number, and level by level the same
// cluster count and triplets (counted: where ties could differ they would show here) and
// the energy within 1%. Returns the number of identical levels.
size_t ExpectSameLevels(GlContext& context, const MeshProblem& problem,
                        const MultilevelOptions& options) {
  LevelsSink cpu, gpu;
  const absl::StatusOr<MultilevelSummary> on_cpu = RunMultilevel(problem, options, cpu);
  const absl::StatusOr<MultilevelSummary> on_gpu =
      RunParallelMultilevelGpu(context, problem, options, gpu);
  return fixtures::ExpectSameTripletLevels(on_gpu, gpu, on_cpu, cpu, /*relative=*/0.01);
}

TEST(PmlGpu, SameLevelsAsTheCpuOnFandiskAllPairs) {
  const fixtures::LoadedMesh& mesh = fixtures::LoadDataFile("fandisk.off");
  EXPECT_GT(ExpectSameLevels(Context(), mesh.problem(), PmlOptions(PmlPairRule::kAll, 1)), 10u);
}

// Ours: the cheaper half of the pairs; the lowest level (200) is reached by the cheapest
// pairs of the last level, chosen as the CPU chooses them.
TEST(PmlGpu, SameLevelsAsTheCpuOnFandiskCheaperHalfDownTo200) {
  const fixtures::LoadedMesh& mesh = fixtures::LoadDataFile("fandisk.off");
  const MultilevelOptions options = PmlOptions(PmlPairRule::kCheaperHalf, 200);
  EXPECT_GT(ExpectSameLevels(Context(), mesh.problem(), options), 10u);
  LevelsSink gpu;
  ASSERT_TRUE(RunParallelMultilevelGpu(Context(), mesh.problem(), options, gpu).ok());
  EXPECT_EQ(gpu.counts.back(), 200u);
}

// cvd-adaptive is CvdEnergy with density-weighted sums: on the GPU too.
TEST(PmlGpu, SameLevelsAsTheCpuWithAdaptiveCvd) {
  const fixtures::LoadedMesh& mesh = fixtures::LoadDataFile("fandisk.off");
  ExpectSameLevels(Context(), mesh.problem(MeshEnergyKind::kCvdAdaptive),
                   PmlOptions(PmlPairRule::kAll, 20));
}

// A flat grid without jitter: every merge cost comes in many equal copies, so the levels
// follow the ties rule (equal costs to the larger id) and the kept ids throughout.
TEST(PmlGpu, SameLevelsAsTheCpuOnARegularGridFullOfTies) {
  const fixtures::LoadedMesh mesh = fixtures::Load(meshes::MakeJitteredGrid(24, 40, 0.0f));
  ExpectSameLevels(Context(), mesh.problem(), PmlOptions(PmlPairRule::kAll, 1));
  const fixtures::LoadedMesh jittered = fixtures::Load(meshes::MakeJitteredGrid(24, 40, 0.3f));
  ExpectSameLevels(Context(), jittered.problem(), PmlOptions(PmlPairRule::kCheaperHalf, 1));
}

// With at most 16 work groups per grid dimension the passes over faces and edges run as
// 2-D grids (12,946 faces: 51 groups; 38,838 directed edges: 152) and give the same levels.
TEST(PmlGpu, TwoDimensionalGridsGiveTheSameLevels) {
  const fixtures::LoadedMesh& mesh = fixtures::LoadDataFile("fandisk.off");
  GlContextOptions options;
  options.max_groups_per_dimension = 16;
  absl::StatusOr<std::unique_ptr<GlContext>> capped = GlContext::Create(options);
  ASSERT_TRUE(capped.ok()) << capped.status();
  ExpectSameLevels(**capped, mesh.problem(), PmlOptions(PmlPairRule::kAll, 100));
}

// The triplets of every level, applied to the previous labels, give the labels the GPU
// holds after the level, exactly; each triplet's old cluster is the face's previous one.
TEST(PmlGpu, TripletsRebuildTheGpuLabelsAtEveryLevel) {
  const fixtures::LoadedMesh& mesh = fixtures::LoadDataFile("fandisk.off");
  const CvdEnergy energy(mesh.measures);
  const size_t n = mesh.mesh.num_faces();
  std::vector<CvdSums> sums(n);
  for (uint32_t f = 0; f < n; ++f) sums[f] = energy.face_sums(f);
  absl::StatusOr<PmlLevelsGpu> levels = PmlLevelsGpu::Create(Context(), sums, mesh.adjacency);
  ASSERT_TRUE(levels.ok()) << levels.status();
  std::vector<uint32_t> labels(n);
  for (uint32_t f = 0; f < n; ++f) labels[f] = f;
  uint32_t clusters = static_cast<uint32_t>(n);
  PmlLevelGpu level;
  int checked = 0;
  for (;;) {
    absl::StatusOr<bool> merged = levels->Level(PmlPairRule::kAll, clusters, 1, level);
    ASSERT_TRUE(merged.ok()) << merged.status();
    if (!*merged) break;
    EXPECT_GT(level.merged, 0u);
    EXPECT_FALSE(level.element.empty());
    for (size_t i = 0; i < level.element.size(); ++i) {
      ASSERT_EQ(labels[level.element[i]], level.from_cluster[i]);
      EXPECT_NE(level.to_cluster[i], level.from_cluster[i]);
      labels[level.element[i]] = level.to_cluster[i];
    }
    clusters -= level.merged;
    absl::StatusOr<std::vector<uint32_t>> on_gpu = levels->Labels();
    ASSERT_TRUE(on_gpu.ok()) << on_gpu.status();
    ASSERT_EQ(*on_gpu, labels) << "level " << checked + 1;
    std::vector<uint32_t> distinct = labels;
    std::sort(distinct.begin(), distinct.end());
    EXPECT_EQ(std::unique(distinct.begin(), distinct.end()) - distinct.begin(), clusters);
    ++checked;
  }
  EXPECT_EQ(clusters, 1u);  // fandisk is one component
  EXPECT_GT(checked, 10);
}

TEST(PmlGpu, RefusesWhatItDoesNotCover) {
  const fixtures::LoadedMesh& mesh = fixtures::LoadDataFile("fandisk.off");
  LevelsSink sink;
  MultilevelOptions emlo = PmlOptions(PmlPairRule::kAll, 10);
  emlo.optimizer = MultilevelOptions::Optimizer::kEmlo;
  EXPECT_EQ(RunParallelMultilevelGpu(Context(), mesh.problem(), emlo, sink).status().code(),
            absl::StatusCode::kUnimplemented);
  EXPECT_EQ(RunParallelMultilevelGpu(Context(), mesh.problem(MeshEnergyKind::kPlanar),
                                     PmlOptions(PmlPairRule::kAll, 10), sink)
                .status()
                .code(),
            absl::StatusCode::kUnimplemented);
  EXPECT_TRUE(sink.counts.empty());  // nothing reported
  EXPECT_FALSE(PmlGpuUnsupported(emlo, MeshEnergyKind::kCvd).empty());
  EXPECT_TRUE(PmlGpuUnsupported(PmlOptions(PmlPairRule::kAll, 10), MeshEnergyKind::kCvd).empty());
}

// A GL error injected into each pass (gpu/context/pass.h) is the run's error, named by
// pass; the context works again afterwards.
TEST(PmlGpu, InjectedGlFailureIsACleanError) {
  const fixtures::LoadedMesh mesh = fixtures::Load(meshes::MakeJitteredGrid(10, 10, 0.2f));
  for (const char* pass : {"pml odes", "pml collapse", "pml triplets"}) {
    fixtures::ExpectGlFailureInPass(pass, [&] {
      LevelsSink sink;
      return RunParallelMultilevelGpu(Context(), mesh.problem(), PmlOptions(PmlPairRule::kAll, 1),
                                      sink);
    });
  }
  LevelsSink sink;
  absl::StatusOr<MultilevelSummary> again =
      RunParallelMultilevelGpu(Context(), mesh.problem(), PmlOptions(PmlPairRule::kAll, 1), sink);
  ASSERT_TRUE(again.ok()) << again.status();
  EXPECT_EQ(again->final_clusters, 1u);
}

// Buffers are sized from the stated bound: capped below it, RESOURCE_EXHAUSTED by pass.
TEST(PmlGpu, BuffersOverTheLimitAreResourceExhausted) {
  const fixtures::LoadedMesh mesh = fixtures::Load(meshes::MakeJitteredGrid(20, 20, 0.2f));
  GlContextOptions options;
  options.max_storage_buffer_bytes = 16 * static_cast<int64_t>(mesh.mesh.num_faces());
  absl::StatusOr<std::unique_ptr<GlContext>> small = GlContext::Create(options);
  ASSERT_TRUE(small.ok()) << small.status();
  LevelsSink sink;
  absl::StatusOr<MultilevelSummary> result =
      RunParallelMultilevelGpu(**small, mesh.problem(), PmlOptions(PmlPairRule::kAll, 1), sink);
  EXPECT_EQ(result.status().code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(result.status().message(), HasSubstr("GPU pass 'pml odes'"));
}

// Cancellation is checked between levels: a sink that sets the flag at level 3 stops the
// run there with CANCELLED.
TEST(PmlGpu, CancelledBetweenLevels) {
  const fixtures::LoadedMesh& mesh = fixtures::LoadDataFile("fandisk.off");
  std::atomic<bool> cancel{false};
  fixtures::CancelAtLevel<LevelsSink> sink(cancel, 3);
  MultilevelOptions options = PmlOptions(PmlPairRule::kAll, 1);
  options.cancel = &cancel;
  absl::StatusOr<MultilevelSummary> result =
      RunParallelMultilevelGpu(Context(), mesh.problem(), options, sink);
  EXPECT_EQ(result.status().code(), absl::StatusCode::kCancelled);
  EXPECT_EQ(sink.counts.size(), 4u);  // level 0 and levels 1-3
}

// Several components (two grids apart and a lone triangle): the levels stop at one
// cluster per component, as the CPU's do.
TEST(PmlGpu, StopsAtOneClusterPerComponent) {
  TriangleMesh mesh = meshes::MakeJitteredGrid(8, 12, 0.2f, 5);
  const TriangleMesh second = meshes::MakeJitteredGrid(6, 6, 0.2f, 7);
  const uint32_t offset = static_cast<uint32_t>(mesh.positions.size() / 3);
  for (size_t i = 0; i < second.positions.size(); ++i) {
    mesh.positions.push_back(second.positions[i] + (i % 3 == 0 ? 100.0f : 0.0f));
  }
  for (uint32_t v : second.indices) mesh.indices.push_back(v + offset);
  const uint32_t lone = static_cast<uint32_t>(mesh.positions.size() / 3);
  mesh.positions.insert(mesh.positions.end(), {-50, 0, 0, -49, 0, 0, -50, 1, 0});
  mesh.indices.insert(mesh.indices.end(), {lone, lone + 1, lone + 2});
  const fixtures::LoadedMesh loaded = fixtures::Load(std::move(mesh));
  ExpectSameLevels(Context(), loaded.problem(), PmlOptions(PmlPairRule::kAll, 1));
  LevelsSink sink;
  absl::StatusOr<MultilevelSummary> gpu =
      RunParallelMultilevelGpu(Context(), loaded.problem(), PmlOptions(PmlPairRule::kAll, 1), sink);
  ASSERT_TRUE(gpu.ok()) << gpu.status();
  EXPECT_EQ(gpu->final_clusters, 3u);
}

// The plan (core/cluster/registry.cc): PML's levels go to the GPU for merges only (and BB:
// pml_bb_gpu_test.cc) and the CVD energies, with device gpu even on llvmpipe, with auto
// only on hardware.
TEST(PmlGpuPlan, TheClusterStageGoesToTheGpuWhereTheGpuCoversIt) {
  const DeviceCaps hardware{true, false, "NVIDIA H100"};
  const DeviceCaps software{true, true, "llvmpipe"};
  auto device_of = [](const DeviceCaps& caps, DeviceChoice choice, const char* energy,
                      const char* optimizer) -> std::string {
    JobRequest request;
    request.algorithm = FindAlgorithm(InputKind::kMesh, "pml");
    request.energy = FindEnergy(InputKind::kMesh, energy);
    request.clusters = 10;
    request.device = choice;
    request.options = {{"optimizer", optimizer}};
    absl::StatusOr<JobPlan> plan = PlanJob(request);
    EXPECT_TRUE(plan.ok()) << plan.status();
    if (!plan.ok() || !PlanDevices(caps, *plan).ok()) return "error";
    const StagePlan* stage = FindStage(*plan, "cluster");
    return stage == nullptr ? "none" : StageDeviceName(*stage, caps);
  };
  EXPECT_EQ(device_of(software, DeviceChoice::kGpu, "cvd", "none"), "llvmpipe");
  EXPECT_EQ(device_of(software, DeviceChoice::kGpu, "cvd-adaptive", "none"), "llvmpipe");
  EXPECT_EQ(device_of(software, DeviceChoice::kAuto, "cvd", "none"), "cpu");
  EXPECT_EQ(device_of(hardware, DeviceChoice::kAuto, "cvd", "none"), "NVIDIA H100");
  EXPECT_EQ(device_of(hardware, DeviceChoice::kCpu, "cvd", "none"), "cpu");
  EXPECT_EQ(device_of(hardware, DeviceChoice::kGpu, "cvd", "emlo"), "cpu");
  EXPECT_EQ(device_of(hardware, DeviceChoice::kGpu, "planar", "none"), "cpu");
  // HC and ML keep their levels on the CPU.
  JobRequest ml;
  ml.algorithm = FindAlgorithm(InputKind::kMesh, "ml");
  ml.device = DeviceChoice::kGpu;
  ml.options = {{"optimizer", "none"}};
  absl::StatusOr<JobPlan> plan = PlanJob(ml);
  ASSERT_TRUE(plan.ok()) << plan.status();
  ASSERT_TRUE(PlanDevices(hardware, *plan).ok());
  EXPECT_EQ(FindStage(*plan, "cluster")->device, StageDevice::kCpu);
}

}  // namespace
}  // namespace mlclust::gpu
