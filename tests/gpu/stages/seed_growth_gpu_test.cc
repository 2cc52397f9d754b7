// The initial growth from seeds on the GPU (gpu/kernels/seed_growth.h, section 5.2,
// Fig. 5.9) against the CPU's growth rounds (core/cluster/mesh_clustering.h) and against
// the rule written out here as a full Jacobi sweep per round; the seeding stage with its
// growth on the GPU (gpu/stages/seed_growth_gpu.h) against core's InitialClusters.
#include "gpu/stages/seed_growth_gpu.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <numeric>
#include <random>
#include <vector>

#include "core/cluster/mesh_clustering.h"
#include "gpu/kernels/seed_growth.h"
#include "gpu/tools/test_meshes.h"
#include "tests/fixtures/gl_test_context.h"
#include "tests/fixtures/test_meshes.h"

namespace mlclust::gpu {
namespace {

using ::mlclust::testing::Load;
using ::mlclust::testing::LoadedMesh;
using ::mlclust::testing::SharedGlContext;

constexpr uint32_t kFree = 0xFFFFFFFFu;

// Fig. 5.9 as written: every round, every free face looks at all three neighbours'
// labels of the round before and takes the smallest cluster id among them; until a
// round assigns nothing. A full sweep per round (the GPU's shape, not the CPU's frontier).
std::vector<uint32_t> RoundsAsWritten(const FaceAdjacency& adjacency,
                                      const std::vector<uint32_t>& seeds) {
  std::vector<uint32_t> labels(adjacency.num_faces(), kFree);
  for (uint32_t c = 0; c < seeds.size(); ++c) labels[seeds[c]] = c;
  for (bool assigned = true; assigned;) {
    assigned = false;
    std::vector<uint32_t> next = labels;
    for (size_t f = 0; f < labels.size(); ++f) {
      if (labels[f] != kFree) continue;
      for (FaceId g : adjacency.neighbours[f]) {
        if (g.valid()) next[f] = std::min(next[f], labels[g.value()]);
      }
      assigned = assigned || next[f] != kFree;
    }
    labels.swap(next);
  }
  return labels;
}

std::vector<uint32_t> RandomSeeds(size_t faces, uint32_t count, uint32_t seed) {
  std::vector<uint32_t> all(faces);
  std::iota(all.begin(), all.end(), 0u);
  std::shuffle(all.begin(), all.end(), std::mt19937(seed));
  all.resize(count);
  return all;
}

std::vector<uint32_t> Values(const std::vector<ClusterId>& labels) {
  std::vector<uint32_t> out;
  out.reserve(labels.size());
  for (ClusterId c : labels) out.push_back(c.value());
  return out;
}

// The CPU's kRounds through the public entry (all faces reached).
std::vector<uint32_t> CpuRounds(const LoadedMesh& mesh, const std::vector<uint32_t>& seeds) {
  const std::vector<FaceId> typed(seeds.begin(), seeds.end());
  absl::StatusOr<std::vector<ClusterId>> labels =
      GrowClustersFromSeeds(mesh.problem(), typed, SeedOptions::Growth::kRounds, nullptr);
  EXPECT_TRUE(labels.ok()) << labels.status();
  return labels.ok() ? Values(*labels) : std::vector<uint32_t>{};
}

std::vector<uint32_t> Gpu(GlContext& context, const FaceAdjacency& adjacency,
                          const std::vector<uint32_t>& seeds, uint32_t* rounds = nullptr) {
  absl::StatusOr<SeedGrowthGpuResult> grown = GrowSeedsInRoundsGpu(context, adjacency, seeds);
  EXPECT_TRUE(grown.ok()) << grown.status();
  if (!grown.ok()) return {};
  if (rounds != nullptr) *rounds = grown->rounds;
  return grown->labels;
}

// A triangle strip of 12 faces, face k on vertices k, k+1, k+2: a path of faces 0-1-...-11.
TriangleMesh Strip() {
  TriangleMesh mesh;
  for (uint32_t v = 0; v < 14; ++v) {
    mesh.positions.insert(mesh.positions.end(), {0.5f * v, static_cast<float>(v % 2), 0.0f});
  }
  for (uint32_t k = 0; k < 12; ++k) {
    if (k % 2 == 0) {
      mesh.indices.insert(mesh.indices.end(), {k, k + 2, k + 1});
    } else {
      mesh.indices.insert(mesh.indices.end(), {k, k + 1, k + 2});
    }
  }
  return mesh;
}

// Seeds at faces 0 and 10 of the strip reach face 5 in the same round (5 steps from
// both), and it takes cluster 0, whichever seed that is.
TEST(GpuSeedGrowthTest, TheSmallestClusterIdWinsATie) {
  const LoadedMesh strip = Load(Strip());
  const FaceAdjacency& adjacency = strip.adjacency;
  ASSERT_EQ(adjacency.num_faces(), 12u);
  for (uint32_t f = 0; f + 1 < 12; ++f) {
    const auto& around = adjacency.neighbours[f];
    ASSERT_NE(std::find(around.begin(), around.end(), FaceId(f + 1)), around.end()) << f;
  }
  for (const std::vector<uint32_t>& seeds :
       {std::vector<uint32_t>{0, 10}, std::vector<uint32_t>{10, 0}}) {
    const std::vector<uint32_t> written = RoundsAsWritten(adjacency, seeds);
    EXPECT_EQ(Gpu(SharedGlContext(), adjacency, seeds), written);
    EXPECT_EQ(CpuRounds(strip, seeds), written);
    EXPECT_EQ(written[5], 0u);
    EXPECT_EQ(written[4], seeds[0] == 0 ? 0u : 1u);
    EXPECT_EQ(written[6], seeds[0] == 0 ? 1u : 0u);
    EXPECT_EQ(written[seeds[0]], 0u);
    EXPECT_EQ(written[seeds[1]], 1u);
  }
}

TEST(GpuSeedGrowthTest, EqualsTheCpuOnTheTestMeshes) {
  const LoadedMesh grid = Load(gpu::testing::MakeJitteredGrid(60, 60, 0.2f));
  const LoadedMesh sphere = Load(gpu::testing::MakeIcosphere(4));
  for (const LoadedMesh* mesh : {&grid, &sphere}) {
    for (uint32_t count : {1u, 7u, 200u}) {
      const std::vector<uint32_t> seeds = RandomSeeds(mesh->adjacency.num_faces(), count, count);
      uint32_t rounds = 0;
      const std::vector<uint32_t> gpu = Gpu(SharedGlContext(), mesh->adjacency, seeds, &rounds);
      EXPECT_EQ(gpu, CpuRounds(*mesh, seeds)) << count << " seeds";
      EXPECT_EQ(gpu, RoundsAsWritten(mesh->adjacency, seeds)) << count << " seeds";
      EXPECT_GT(rounds, 0u);
      // Fewer seeds, more rounds: one seed on the grid needs about its diameter.
      if (count == 1) {
        EXPECT_GT(rounds, 30u);
      }
    }
  }
}

// Section 5.2's rule and l. 671's energy-free growth (each cluster in turn taking the free
// faces across its boundary) give the same partition: a face free after round r - 1 has
// only neighbours assigned in round r - 1, and the first cluster in seed order to reach it
// is the one with the smallest id.
TEST(GpuSeedGrowthTest, RoundsEqualTheEnergyFreeGrowth) {
  const LoadedMesh sphere = Load(gpu::testing::MakeIcosphere(4));
  const std::vector<uint32_t> seeds = RandomSeeds(sphere.adjacency.num_faces(), 50, 3);
  const std::vector<FaceId> typed(seeds.begin(), seeds.end());
  absl::StatusOr<std::vector<ClusterId>> free =
      GrowClustersFromSeeds(sphere.problem(), typed, SeedOptions::Growth::kEnergyFree, nullptr);
  ASSERT_TRUE(free.ok()) << free.status();
  EXPECT_EQ(Values(*free), CpuRounds(sphere, seeds));
}

// Two spheres, seeds on the first only: the second's faces stay free on the GPU as in the
// rule; the CPU's public entry refuses such seeds (a component without one).
TEST(GpuSeedGrowthTest, FacesNoSeedReachesStayFree) {
  TriangleMesh two = gpu::testing::MakeIcosphere(2);
  const TriangleMesh other = gpu::testing::MakeIcosphere(2, 1.0, 5.0);
  const uint32_t offset = static_cast<uint32_t>(two.num_vertices());
  const size_t first_faces = two.num_faces();
  two.positions.insert(two.positions.end(), other.positions.begin(), other.positions.end());
  for (uint32_t v : other.indices) two.indices.push_back(v + offset);
  const LoadedMesh mesh = Load(std::move(two));
  const std::vector<uint32_t> seeds = RandomSeeds(first_faces, 5, 9);
  const std::vector<uint32_t> gpu = Gpu(SharedGlContext(), mesh.adjacency, seeds);
  EXPECT_EQ(gpu, RoundsAsWritten(mesh.adjacency, seeds));
  ASSERT_EQ(gpu.size(), 2 * first_faces);
  for (size_t f = 0; f < gpu.size(); ++f) {
    EXPECT_EQ(gpu[f] == kFree, f >= first_faces) << f;
  }
  const std::vector<FaceId> typed(seeds.begin(), seeds.end());
  EXPECT_EQ(GrowClustersFromSeeds(mesh.problem(), typed, SeedOptions::Growth::kRounds, nullptr)
                .status()
                .code(),
            absl::StatusCode::kInvalidArgument);
}

// Two groups per grid dimension: every round is several dispatches of a 2-D grid.
TEST(GpuSeedGrowthTest, ASmallGridSplitsEachRound) {
  GlContextOptions options;
  options.max_groups_per_dimension = 2;
  std::unique_ptr<GlContext> context = ::mlclust::testing::MakeGlContext(options);
  ASSERT_NE(context, nullptr);
  const LoadedMesh grid = Load(gpu::testing::MakeJitteredGrid(40, 40, 0.2f));  // 3200 faces
  const std::vector<uint32_t> seeds = RandomSeeds(grid.adjacency.num_faces(), 20, 5);
  EXPECT_EQ(Gpu(*context, grid.adjacency, seeds), CpuRounds(grid, seeds));
}

TEST(GpuSeedGrowthTest, Errors) {
  const LoadedMesh grid = Load(gpu::testing::MakeJitteredGrid(10, 10, 0.1f));  // 200 faces
  const FaceAdjacency& adjacency = grid.adjacency;
  // A seed out of range.
  EXPECT_EQ(GrowSeedsInRoundsGpu(SharedGlContext(), adjacency, std::vector<uint32_t>{200})
                .status()
                .code(),
            absl::StatusCode::kInvalidArgument);
  // Cancelled between rounds.
  std::atomic<bool> cancel{true};
  EXPECT_EQ(GrowSeedsInRoundsGpu(SharedGlContext(), adjacency, std::vector<uint32_t>{0}, &cancel)
                .status()
                .code(),
            absl::StatusCode::kCancelled);
  // The adjacency one byte over the storage buffer limit.
  GlContextOptions small;
  small.max_storage_buffer_bytes = 12 * 200 - 1;
  std::unique_ptr<GlContext> context = ::mlclust::testing::MakeGlContext(small);
  ASSERT_NE(context, nullptr);
  const absl::Status exhausted =
      GrowSeedsInRoundsGpu(*context, adjacency, std::vector<uint32_t>{0}).status();
  EXPECT_EQ(exhausted.code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(std::string(exhausted.message()), ::testing::HasSubstr("initial growth"));
  // The memory bound: 20 bytes per face and the counter.
  EXPECT_EQ(SeedGrowthMemoryBound(200), 20u * 200 + 4);
  // A GL failure injected into the pass.
  ::mlclust::testing::ExpectGlFailureInPass(kSeedGrowthPass, [&] {
    return GrowSeedsInRoundsGpu(SharedGlContext(), adjacency, std::vector<uint32_t>{0, 50});
  });
}

// The seeding stage with the growth on the GPU equals core's InitialClusters with growth
// rounds: l-neighbourhood seeds reduced to k (both reductions), random seeds, and seeds
// added to a large l.
TEST(GpuSeedGrowthTest, InitialClustersOnTheGpuEqualTheCpus) {
  const LoadedMesh sphere = Load(gpu::testing::MakeIcosphere(4));
  SeedOptions options;
  options.clusters = 40;
  options.growth = SeedOptions::Growth::kRounds;
  std::vector<SeedOptions> cases(4, options);
  cases[1].reduction = SeedOptions::Reduction::kReseedAndRegrow;
  cases[2].method = SeedOptions::Method::kRandom;
  cases[3].level = 12;
  cases[3].add_seeds = true;
  for (size_t i = 0; i < cases.size(); ++i) {
    absl::StatusOr<std::vector<ClusterId>> cpu = InitialClusters(sphere.problem(), cases[i]);
    absl::StatusOr<std::vector<ClusterId>> gpu =
        InitialClustersGpu(SharedGlContext(), sphere.problem(), cases[i]);
    ASSERT_TRUE(cpu.ok()) << cpu.status();
    ASSERT_TRUE(gpu.ok()) << gpu.status();
    EXPECT_EQ(*gpu, *cpu) << "case " << i;
    const std::vector<uint32_t> values = Values(*cpu);
    EXPECT_EQ(*std::max_element(values.begin(), values.end()), 39u) << "case " << i;
  }
  // The GPU's error is the stage's.
  ::mlclust::testing::ExpectGlFailureInPass(kSeedGrowthPass, [&] {
    return InitialClustersGpu(SharedGlContext(), sphere.problem(), options);
  });
}

}  // namespace
}  // namespace mlclust::gpu
