// PML for meshes on the GPU (gpu/stages/multilevel_gpu.h, gpu/kernels/pml_levels.h)
// against the CPU engine's PML (core/cluster/multilevel.h, merges only), on llvmpipe.
#include "gpu/stages/multilevel_gpu.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <tuple>

#include "core/cluster/multilevel.h"
#include "core/cluster/registry.h"
#include "gpu/context/gl_context.h"
#include "gpu/kernels/pml_levels.h"
#include "gpu/tools/test_meshes.h"
#include "tests/fixtures/gl_test_context.h"
#include "tests/fixtures/gpu_mesh_levels.h"
#include "tests/fixtures/plan_checks.h"
#include "tests/fixtures/recording_sink.h"
#include "tests/fixtures/test_meshes.h"

namespace mlclust::gpu {
namespace {

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
// cluster count and triplets (as sets: the CPU reports them in merge order, the GPU in face
// order; where ties could differ they would show here) and the energy within 1e-9
// relative (the same changes, summed in another order). Returns the number of levels
// compared.
size_t ExpectSameLevels(GlContext& context, const MeshProblem& problem,
                        const MultilevelOptions& options) {
  return fixtures::ExpectSameLevelsAsCpu(RunParallelMultilevelGpu, context, problem, options,
                                         fixtures::SameLevels::kSortedWithinRounding);
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
  const std::unique_ptr<GlContext> grids = fixtures::MakeTwoDimensionalGridContext();
  ASSERT_NE(grids, nullptr);
  ExpectSameLevels(*grids, mesh.problem(), PmlOptions(PmlPairRule::kAll, 100));
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
  fixtures::ExpectInjectedFailuresAreCleanErrors(RunParallelMultilevelGpu, mesh.problem(),
                                                 PmlOptions(PmlPairRule::kAll, 1),
                                                 {"pml odes", "pml collapse", "pml triplets"});
}

// Buffers are sized from the stated bound: capped below it, RESOURCE_EXHAUSTED by pass.
TEST(PmlGpu, BuffersOverTheLimitAreResourceExhausted) {
  const fixtures::LoadedMesh mesh = fixtures::Load(meshes::MakeJitteredGrid(20, 20, 0.2f));
  fixtures::ExpectResourceExhaustedBelowTheBound(RunParallelMultilevelGpu, mesh.problem(),
                                                 PmlOptions(PmlPairRule::kAll, 1), "pml odes");
}

// Cancellation is checked between levels: a sink that sets the flag at level 3 stops the
// run there with CANCELLED.
TEST(PmlGpu, CancelledBetweenLevels) {
  const fixtures::LoadedMesh& mesh = fixtures::LoadDataFile("fandisk.off");
  // Level 0 and levels 1-3.
  EXPECT_EQ(fixtures::LevelsBeforeCancel(RunParallelMultilevelGpu, mesh.problem(),
                                         PmlOptions(PmlPairRule::kAll, 1), 3),
            4u);
}

// Several components (two grids apart and a lone triangle): the levels stop at one
// cluster per component, as the CPU's do.
TEST(PmlGpu, StopsAtOneClusterPerComponent) {
  const fixtures::LoadedMesh loaded = fixtures::Load(fixtures::ThreeComponentMesh());
  ExpectSameLevels(Context(), loaded.problem(), PmlOptions(PmlPairRule::kAll, 1));
  LevelsSink sink;
  absl::StatusOr<MultilevelSummary> gpu =
      RunParallelMultilevelGpu(Context(), loaded.problem(), PmlOptions(PmlPairRule::kAll, 1), sink);
  ASSERT_TRUE(gpu.ok()) << gpu.status();
  EXPECT_EQ(gpu->final_clusters, 3u);
}

// The plan (core/cluster/registry.cc): PML's levels go to the GPU for merges only (and BB:
// pml_bb_gpu_test.cc) and the CVD energies, with device gpu even on llvmpipe, with auto
// only on hardware. (HC's and ML's: hierarchy_gpu_test.cc, pml_bb_gpu_test.cc.)
TEST(PmlGpuPlan, TheClusterStageGoesToTheGpuWhereTheGpuCoversIt) {
  const DeviceCaps hardware{true, false, "NVIDIA H100"};
  const DeviceCaps software{true, true, "llvmpipe"};
  auto device_of = [](const DeviceCaps& caps, DeviceChoice choice, const char* energy,
                      const char* optimizer) {
    return fixtures::ClusterStageDeviceFor(caps, InputKind::kMesh, "pml", energy, choice,
                                           {{"optimizer", optimizer}});
  };
  EXPECT_EQ(device_of(software, DeviceChoice::kGpu, "cvd", "none"), "llvmpipe");
  EXPECT_EQ(device_of(software, DeviceChoice::kGpu, "cvd-adaptive", "none"), "llvmpipe");
  EXPECT_EQ(device_of(software, DeviceChoice::kAuto, "cvd", "none"), "cpu");
  EXPECT_EQ(device_of(hardware, DeviceChoice::kAuto, "cvd", "none"), "NVIDIA H100");
  EXPECT_EQ(device_of(hardware, DeviceChoice::kCpu, "cvd", "none"), "cpu");
  EXPECT_EQ(device_of(hardware, DeviceChoice::kGpu, "cvd", "emlo"), "cpu");
  EXPECT_EQ(device_of(hardware, DeviceChoice::kGpu, "planar", "none"), "cpu");
}

}  // namespace
}  // namespace mlclust::gpu
