// HC for meshes on the GPU (gpu/stages/hierarchy_gpu.h, gpu/kernels/hc_levels.h) against
// the CPU engine's HC (core/cluster/multilevel.h, optimizer none), on llvmpipe.
#include "gpu/stages/hierarchy_gpu.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <utility>

#include "core/cluster/multilevel.h"
#include "core/cluster/registry.h"
#include "gpu/context/gl_context.h"
#include "gpu/kernels/hc_levels.h"
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

// Every level: its count, energy and triplets in the order reported (the GPU logs a
// merged cluster's faces in the CPU's member order).
using LevelsSink = fixtures::TripletSink;

MultilevelOptions HcOptions(uint32_t lowest) {
  MultilevelOptions options;
  options.optimizer = MultilevelOptions::Optimizer::kNone;
  options.min_clusters = lowest;
  return options;
}

// The GPU's levels against the CPU's: the same number, and level by level the same
// cluster count, the same triplets in the same order and the same energy to the last
// digit (the same merges in the same order, the same fp64 operations). Returns the
// number of levels compared.
size_t ExpectSameLevels(GlContext& context, const MeshProblem& problem,
                        const MultilevelOptions& options) {
  return fixtures::ExpectSameLevelsAsCpu(RunHierarchyGpu, context, problem, options,
                                         fixtures::SameLevels::kExact);
}

TEST(HcGpu, SameLevelsAsTheCpuOnFandiskDownToOneCluster) {
  const fixtures::LoadedMesh& mesh = fixtures::LoadDataFile("fandisk.off");
  EXPECT_EQ(ExpectSameLevels(Context(), mesh.problem(), HcOptions(1)), mesh.mesh.num_faces());
}

// cvd-adaptive is CvdEnergy with density-weighted sums; ties by id alone (the former
// rule, ties_to_fewest_faces off).
TEST(HcGpu, SameLevelsAsTheCpuWithAdaptiveCvdAndTiesById) {
  const fixtures::LoadedMesh& mesh = fixtures::LoadDataFile("fandisk.off");
  ExpectSameLevels(Context(), mesh.problem(MeshEnergyKind::kCvdAdaptive), HcOptions(50));
  MultilevelOptions by_id = HcOptions(50);
  by_id.ties_to_fewest_faces = false;
  ExpectSameLevels(Context(), mesh.problem(), by_id);
}

// A flat grid without jitter: every merge cost comes in many equal copies, so the order
// of the merges follows the ties rules (the fewer faces, then the smaller id; the ODE to
// the larger id) and the kept ids throughout.
TEST(HcGpu, SameLevelsAsTheCpuOnARegularGridFullOfTies) {
  const fixtures::LoadedMesh mesh = fixtures::Load(meshes::MakeJitteredGrid(24, 40, 0.0f));
  ExpectSameLevels(Context(), mesh.problem(), HcOptions(1));
  MultilevelOptions by_id = HcOptions(1);
  by_id.ties_to_fewest_faces = false;
  ExpectSameLevels(Context(), mesh.problem(), by_id);
}

// With at most 16 work groups per grid dimension the start's passes over faces, edges
// and tree nodes run as 2-D grids (12,946 faces: 51 groups; 38,838 directed edges: 152)
// and give the same levels.
TEST(HcGpu, TwoDimensionalGridsGiveTheSameLevels) {
  const fixtures::LoadedMesh& mesh = fixtures::LoadDataFile("fandisk.off");
  const std::unique_ptr<GlContext> grids = fixtures::MakeTwoDimensionalGridContext();
  ASSERT_NE(grids, nullptr);
  ExpectSameLevels(*grids, mesh.problem(), HcOptions(100));
}

// The triplets of every step, applied to the previous labels, give the labels the GPU
// holds after each batch, exactly; each triplet's old cluster is the face's previous one.
TEST(HcGpu, TripletsRebuildTheGpuLabels) {
  const fixtures::LoadedMesh& mesh = fixtures::LoadDataFile("fandisk.off");
  const CvdEnergy energy(mesh.measures);
  const size_t n = mesh.mesh.num_faces();
  std::vector<CvdSums> sums(n);
  for (uint32_t f = 0; f < n; ++f) sums[f] = energy.face_sums(f);
  absl::StatusOr<HcLevelsGpu> levels = HcLevelsGpu::Create(Context(), sums, mesh.adjacency, true);
  ASSERT_TRUE(levels.ok()) << levels.status();
  std::vector<uint32_t> labels(n);
  for (uint32_t f = 0; f < n; ++f) labels[f] = f;
  uint32_t clusters = static_cast<uint32_t>(n);
  HcBatchGpu batch;
  int batches = 0;
  for (uint32_t size = 1;; size = std::min<uint32_t>(3 * size, 1000)) {
    ASSERT_TRUE(levels->Steps(1, size, batch).ok());
    if (batch.steps.empty()) break;
    EXPECT_LE(batch.steps.size(), size);
    for (const HcStepGpu& step : batch.steps) {
      EXPECT_NE(step.keep, step.gone);
      EXPECT_GT(step.count, 0u);
      for (uint32_t i = step.first; i < step.first + step.count; ++i) {
        ASSERT_EQ(labels[batch.faces[i]], step.gone);
        labels[batch.faces[i]] = step.keep;
      }
      --clusters;
    }
    absl::StatusOr<std::vector<uint32_t>> on_gpu = levels->Labels();
    ASSERT_TRUE(on_gpu.ok()) << on_gpu.status();
    ASSERT_EQ(*on_gpu, labels) << "batch " << batches;
    std::vector<uint32_t> distinct = labels;
    std::sort(distinct.begin(), distinct.end());
    EXPECT_EQ(std::unique(distinct.begin(), distinct.end()) - distinct.begin(), clusters);
    ++batches;
  }
  EXPECT_EQ(clusters, 1u);  // fandisk is one component
  EXPECT_GT(batches, 10);
}

TEST(HcGpu, RefusesWhatItDoesNotCover) {
  const fixtures::LoadedMesh& mesh = fixtures::LoadDataFile("fandisk.off");
  LevelsSink sink;
  MultilevelOptions emlo = HcOptions(10);
  emlo.optimizer = MultilevelOptions::Optimizer::kEmlo;
  EXPECT_EQ(RunHierarchyGpu(Context(), mesh.problem(), emlo, sink).status().code(),
            absl::StatusCode::kUnimplemented);
  MultilevelOptions pml = HcOptions(10);
  pml.parallel = true;
  EXPECT_EQ(RunHierarchyGpu(Context(), mesh.problem(), pml, sink).status().code(),
            absl::StatusCode::kUnimplemented);
  EXPECT_EQ(RunHierarchyGpu(Context(), mesh.problem(MeshEnergyKind::kPlanar), HcOptions(10), sink)
                .status()
                .code(),
            absl::StatusCode::kUnimplemented);
  // Per-polygon clustering (problem.polygons) stays on the CPU.
  const std::vector<uint32_t> one_each(mesh.mesh.num_faces(), 1);
  absl::StatusOr<MeshPolygons> polygons = MakeMeshPolygons(one_each, mesh.adjacency);
  ASSERT_TRUE(polygons.ok()) << polygons.status();
  MeshProblem per_polygon = mesh.problem();
  per_polygon.polygons = &*polygons;
  EXPECT_EQ(RunHierarchyGpu(Context(), per_polygon, HcOptions(10), sink).status().code(),
            absl::StatusCode::kUnimplemented);
  EXPECT_TRUE(sink.counts.empty());  // nothing reported
  EXPECT_FALSE(HcGpuUnsupported(emlo, MeshEnergyKind::kCvd).empty());
  EXPECT_TRUE(HcGpuUnsupported(HcOptions(10), MeshEnergyKind::kCvd).empty());
}

// A GL error injected into each pass (gpu/context/pass.h) is the run's error, named by
// pass; the context works again afterwards.
TEST(HcGpu, InjectedGlFailureIsACleanError) {
  const fixtures::LoadedMesh mesh = fixtures::Load(meshes::MakeJitteredGrid(10, 10, 0.2f));
  fixtures::ExpectInjectedFailuresAreCleanErrors(RunHierarchyGpu, mesh.problem(), HcOptions(1),
                                                 {"hc odes", "hc collapse", "hc triplets"});
}

// Buffers are sized from the stated bound: capped below it, RESOURCE_EXHAUSTED by pass.
TEST(HcGpu, BuffersOverTheLimitAreResourceExhausted) {
  const fixtures::LoadedMesh mesh = fixtures::Load(meshes::MakeJitteredGrid(20, 20, 0.2f));
  EXPECT_GT(HcLevelsMemoryBound(mesh.mesh.num_faces(), 3 * mesh.mesh.num_faces()),
            100 * mesh.mesh.num_faces());
  fixtures::ExpectResourceExhaustedBelowTheBound(RunHierarchyGpu, mesh.problem(), HcOptions(1),
                                                 "hc odes");
}

// Cancellation is checked between batches of steps: a sink that sets the flag at level 3
// stops the run at the end of that batch (the first batch has 64 steps) with CANCELLED.
TEST(HcGpu, CancelledBetweenBatches) {
  const fixtures::LoadedMesh& mesh = fixtures::LoadDataFile("fandisk.off");
  const size_t levels =
      fixtures::LevelsBeforeCancel(RunHierarchyGpu, mesh.problem(), HcOptions(1), 3);
  // Level 0 and the first batch (at most 64 steps; fewer where the loop budget of a
  // software renderer ends it).
  EXPECT_GE(levels, 4u);
  EXPECT_LE(levels, 65u);
}

// The merges do not depend on how the steps are split into batches (one dispatch each)
// nor on the steps' work group size: one step per batch and the largest batches, with the
// renderer's group size and with the hardware's (64), give the CPU's pairs in its order.
TEST(HcGpu, BatchSizesGiveTheSamePairs) {
  const fixtures::LoadedMesh mesh = fixtures::Load(meshes::MakeJitteredGrid(24, 30, 0.3f));
  class PairSink : public LevelSink {
   public:
    absl::Status OnStart(std::span<const ClusterId> /*labels*/, uint32_t /*count*/,
                         double /*energy*/) override {
      return absl::OkStatus();
    }
    absl::Status OnLevel(const LevelMoves& level) override {
      pairs.push_back({level.to_cluster[0], level.from_cluster[0]});
      return absl::OkStatus();
    }
    std::vector<std::pair<uint32_t, uint32_t>> pairs;
  } cpu;
  ASSERT_TRUE(RunMultilevel(mesh.problem(), HcOptions(1), cpu).ok());
  const CvdEnergy energy(mesh.measures);
  const size_t n = mesh.mesh.num_faces();
  std::vector<CvdSums> sums(n);
  for (uint32_t f = 0; f < n; ++f) sums[f] = energy.face_sums(f);
  for (const auto& [size, group] :
       {std::pair<uint32_t, uint32_t>{1, 0}, {kHcMaxBatch, 0}, {kHcMaxBatch, kHcStepGroup}}) {
    absl::StatusOr<HcLevelsGpu> levels =
        HcLevelsGpu::Create(Context(), sums, mesh.adjacency, true, group);
    ASSERT_TRUE(levels.ok()) << levels.status();
    std::vector<std::pair<uint32_t, uint32_t>> pairs;
    HcBatchGpu batch;
    for (;;) {
      ASSERT_TRUE(levels->Steps(1, size, batch).ok());
      if (batch.steps.empty()) break;
      EXPECT_LE(batch.steps.size(), size);
      for (const HcStepGpu& step : batch.steps) pairs.push_back({step.keep, step.gone});
    }
    EXPECT_EQ(pairs.size(), n - 1);
    EXPECT_EQ(pairs, cpu.pairs) << "batches of " << size << ", group " << group;
  }
}

// Several components (two grids apart and a lone triangle): the levels stop at one
// cluster per component, as the CPU's do.
TEST(HcGpu, StopsAtOneClusterPerComponent) {
  const fixtures::LoadedMesh loaded = fixtures::Load(fixtures::ThreeComponentMesh());
  ExpectSameLevels(Context(), loaded.problem(), HcOptions(1));
  LevelsSink sink;
  absl::StatusOr<MultilevelSummary> gpu =
      RunHierarchyGpu(Context(), loaded.problem(), HcOptions(1), sink);
  ASSERT_TRUE(gpu.ok()) << gpu.status();
  EXPECT_EQ(gpu->final_clusters, 3u);
}

// The plan (core/cluster/registry.cc): HC's steps go to the GPU for the CVD energies with
// device gpu (even on llvmpipe); auto keeps them on the CPU, on hardware too.
TEST(HcGpuPlan, TheClusterStageGoesToTheGpuWhereTheGpuCoversIt) {
  const DeviceCaps hardware{true, false, "NVIDIA H100"};
  const DeviceCaps software{true, true, "llvmpipe"};
  auto device_of = [](const DeviceCaps& caps, DeviceChoice choice, const char* energy) {
    return ::mlclust::testing::ClusterStageDeviceFor(caps, InputKind::kMesh, "hc", energy, choice);
  };
  EXPECT_EQ(device_of(software, DeviceChoice::kGpu, "cvd"), "llvmpipe");
  EXPECT_EQ(device_of(software, DeviceChoice::kGpu, "cvd-adaptive"), "llvmpipe");
  EXPECT_EQ(device_of(software, DeviceChoice::kAuto, "cvd"), "cpu");
  EXPECT_EQ(device_of(hardware, DeviceChoice::kAuto, "cvd"), "cpu");
  EXPECT_EQ(device_of(hardware, DeviceChoice::kGpu, "cvd"), "NVIDIA H100");
  EXPECT_EQ(device_of(hardware, DeviceChoice::kCpu, "cvd"), "cpu");
  EXPECT_EQ(device_of(hardware, DeviceChoice::kGpu, "planar"), "cpu");
}

}  // namespace
}  // namespace mlclust::gpu
