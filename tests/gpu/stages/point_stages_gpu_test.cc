#include "gpu/stages/point_stages_gpu.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <random>

#include "core/base/renumber.h"
#include "core/cluster/detail/ln_kmeans_stages.h"
#include "core/cluster/kmeans.h"
#include "core/cluster/point_clustering.h"
#include "gpu/context/compute.h"
#include "gpu/context/gl_context.h"
#include "gpu/context/pass.h"
#include "gpu/kernels/ln_kmeans.h"
#include "tests/fixtures/gl_test_context.h"

namespace mlclust::gpu {
namespace {

GlContext& Context() { return ::mlclust::testing::SharedGlContext(); }

// m points in d dimensions around `blobs` random centres (unit spread in a box of 40).
PointSet Blobs(uint32_t m, uint32_t d, uint32_t blobs, uint32_t seed) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<float> box(-20, 20);
  std::normal_distribution<float> spread(0, 1);
  std::vector<float> centres(size_t{blobs} * d);
  for (float& c : centres) c = box(random);
  PointSet points;
  points.dims = d;
  points.values.resize(size_t{m} * d);
  for (uint32_t i = 0; i < m; ++i) {
    const uint32_t b = i % blobs;
    for (uint32_t j = 0; j < d; ++j)
      points.values[size_t{i} * d + j] = centres[b * d + j] + spread(random);
  }
  return points;
}

std::vector<ClusterId> Seeds(const PointSet& points, uint32_t k) {
  absl::StatusOr<std::vector<ClusterId>> seeds = SeedPointClusters(points, k, false, 5);
  EXPECT_TRUE(seeds.ok()) << seeds.status();
  return seeds.ok() ? *seeds : std::vector<ClusterId>{};
}

// 60 seeded clusters of 20,000 3-D points with the GPU's brute-force neighbours, the
// assign kernel set to them, and every point to check.
struct AssignCase {
  AssignCase()
      : points(Blobs(20000, 3, 40, 1)),
        compact(RenumberByFirstAppearance(std::span<const ClusterId>(Seeds(points, 60)))),
        clusters(points, compact.dense, compact.size()),
        counts(compact.size()),
        check(points.num_points()) {
    for (uint32_t c = 0; c < counts.size(); ++c) {
      counts[c] = static_cast<uint32_t>(clusters.count(c));
    }
    for (uint32_t i = 0; i < check.size(); ++i) check[i] = i;
  }
  // The kernel with the clusters and their neighbours set (the neighbours from the GPU's
  // brute force, into `clusters` too).
  absl::StatusOr<LnKmeansKernel> Kernel() {
    absl::StatusOr<LnKmeansKernel> kernel =
        LnKmeansKernel::Create(Context(), points, clusters.origin(), compact.size());
    if (!kernel.ok()) return kernel;
    absl::Status status =
        kernel->SetClusters(clusters.centroids(), clusters.neighbour_table(), counts);
    if (status.ok()) status = kernel->InitialNeighbours(clusters.neighbour_table());
    if (status.ok()) {
      status = kernel->SetClusters(clusters.centroids(), clusters.neighbour_table(), counts);
    }
    if (!status.ok()) return status;
    return kernel;
  }

  PointSet points;
  Renumbering<ClusterId> compact;
  mlclust::detail::PointClusters clusters;
  std::vector<uint32_t> counts, check;
};

// The assign kernel against ChooseTargets on the same clusters and neighbours: identical
// targets on llvmpipe (fp64, `precise`). The neighbours come from the GPU's brute force.
TEST(LnKmeansKernel, SameTargetsAsChooseTargets) {
  AssignCase test;
  absl::StatusOr<LnKmeansKernel> kernel = test.Kernel();
  ASSERT_TRUE(kernel.ok()) << kernel.status();
  size_t with_neighbours = 0;
  for (uint32_t n : test.clusters.neighbour_table()) {
    with_neighbours += n != mlclust::detail::kNoCluster;
  }
  EXPECT_GT(with_neighbours, 60u);
  std::vector<uint32_t> cpu(test.check.size()), gpu(test.check.size());
  mlclust::detail::ChooseTargets(test.clusters, test.check, cpu);
  ASSERT_TRUE(kernel->Assign(test.clusters.labels(), test.check, gpu).ok());
  size_t moves = 0;
  for (uint32_t t : cpu) moves += t != mlclust::detail::kNoCluster;
  EXPECT_GT(moves, 0u);
  EXPECT_EQ(gpu, cpu);
}

// AssignResident over labels and clusters already in GPU buffers (as the point levels
// hold them) gives ChooseTargets' targets, and with margins ChooseTargets' margins:
// -infinity for a point that moves, else within 1e-9 of the CPU's.
TEST(LnKmeansKernel, ResidentClustersGiveChooseTargetsTargetsAndMargins) {
  AssignCase test;
  absl::StatusOr<LnKmeansKernel> kernel = test.Kernel();
  ASSERT_TRUE(kernel.ok()) << kernel.status();
  std::vector<StorageBuffer> buffers;
  for (const size_t bytes :
       {test.clusters.labels().size_bytes(), test.clusters.centroids().size_bytes(),
        std::span<const uint32_t>(test.clusters.neighbour_table()).size_bytes(),
        test.counts.size() * sizeof(uint32_t)}) {
    absl::StatusOr<StorageBuffer> buffer = StorageBuffer::Create(Context(), bytes);
    ASSERT_TRUE(buffer.ok()) << buffer.status();
    buffers.push_back(*std::move(buffer));
  }
  ASSERT_TRUE(buffers[0].Upload(test.clusters.labels()).ok());
  ASSERT_TRUE(buffers[1].Upload(test.clusters.centroids()).ok());
  ASSERT_TRUE(buffers[2].Upload(std::span<const uint32_t>(test.clusters.neighbour_table())).ok());
  ASSERT_TRUE(buffers[3].Upload(std::span<const uint32_t>(test.counts)).ok());
  const size_t n = test.check.size();
  std::vector<uint32_t> cpu(n), gpu(n);
  std::vector<double> cpu_margin(n), gpu_margin(n);
  mlclust::detail::ChooseTargets(test.clusters, test.check, cpu, cpu_margin);
  ASSERT_TRUE(kernel
                  ->AssignResident({&buffers[0], &buffers[1], &buffers[2], &buffers[3]}, test.check,
                                   gpu, gpu_margin)
                  .ok());
  EXPECT_EQ(gpu, cpu);
  size_t moving = 0;
  for (size_t r = 0; r < n; ++r) {
    if (std::isinf(cpu_margin[r]) && cpu_margin[r] < 0) {
      ++moving;
      EXPECT_TRUE(std::isinf(gpu_margin[r]) && gpu_margin[r] < 0) << r;
    } else {
      EXPECT_NEAR(gpu_margin[r], cpu_margin[r], 1e-9 * (1 + std::abs(cpu_margin[r]))) << r;
    }
  }
  EXPECT_GT(moving, 0u);
  EXPECT_LT(moving, n);
}

// Issue 10: LN k-means inertia within 0.5% of the CPU's (identical on llvmpipe).
TEST(RunLnKmeansGpu, InertiaWithinHalfAPercentOfTheCpu) {
  const PointSet points = Blobs(30000, 3, 50, 2);
  const std::vector<ClusterId> seeds = Seeds(points, 80);
  absl::StatusOr<LnKmeansResult> cpu = RunLnKmeans(points, seeds);
  absl::StatusOr<LnKmeansResult> gpu = RunLnKmeansGpu(Context(), points, seeds);
  ASSERT_TRUE(cpu.ok()) << cpu.status();
  ASSERT_TRUE(gpu.ok()) << gpu.status();
  EXPECT_LT(gpu->energy, gpu->initial_energy);
  EXPECT_NEAR(gpu->energy, cpu->energy, 0.005 * cpu->energy);
  EXPECT_EQ(gpu->labels.size(), points.num_points());
  size_t same = 0;
  for (size_t i = 0; i < gpu->labels.size(); ++i) same += gpu->labels[i] == cpu->labels[i];
  std::printf("LN k-means: energy gpu %.9g cpu %.9g, %zu of %zu labels equal, %u / %u iterations\n",
              gpu->energy, cpu->energy, same, gpu->labels.size(), gpu->iterations, cpu->iterations);
}

// Issue 10: brute-force k-means inertia within 0.5% of the CPU's from the same centres.
TEST(RunLloydGpu, InertiaWithinHalfAPercentOfTheCpu) {
  const PointSet points = Blobs(20000, 4, 30, 3);
  absl::StatusOr<std::vector<float>> centres = KmeansPlusPlusCentres(points, 40, 7);
  ASSERT_TRUE(centres.ok()) << centres.status();
  KmeansOptions options;
  options.clusters = 40;
  absl::StatusOr<KmeansResult> cpu = RunLloyd(points, *centres, options);
  absl::StatusOr<KmeansResult> gpu = RunLloydGpu(Context(), points, *centres, options);
  ASSERT_TRUE(cpu.ok()) << cpu.status();
  ASSERT_TRUE(gpu.ok()) << gpu.status();
  EXPECT_NEAR(gpu->inertia, cpu->inertia, 0.005 * cpu->inertia);
  // Every cluster keeps at least one point.
  std::vector<int> sizes(40, 0);
  for (ClusterId c : gpu->labels) ++sizes[c.value()];
  for (int size : sizes) EXPECT_GT(size, 0);
  std::printf("k-means: inertia gpu %.9g cpu %.9g, %u / %u iterations\n", gpu->inertia,
              cpu->inertia, gpu->iterations, cpu->iterations);
}

TEST(RunLloydGpu, EmptyClustersTakeTheFarthestPoints) {
  // Three centres on one far-away spot: two of them end up empty after the first
  // assignment and must take points.
  const PointSet points = Blobs(3000, 2, 3, 4);
  std::vector<float> centres = {100, 100, 100, 100, 100, 100};
  KmeansOptions options;
  absl::StatusOr<KmeansResult> gpu = RunLloydGpu(Context(), points, centres, options);
  ASSERT_TRUE(gpu.ok()) << gpu.status();
  std::vector<int> sizes(3, 0);
  for (ClusterId c : gpu->labels) ++sizes[c.value()];
  for (int size : sizes) EXPECT_GT(size, 0);
}

// The GPU's Lloyd is RunLloyd's loop (core/cluster/detail/lloyd.h): keep_first_assignment
// keeps the first iteration's partition, exactly what a run of one iteration returns.
TEST(RunLloydGpu, KeepsTheFirstAssignmentAsOneIterationGivesIt) {
  const PointSet points = Blobs(5000, 3, 12, 8);
  absl::StatusOr<std::vector<float>> centres = KmeansPlusPlusCentres(points, 15, 3);
  ASSERT_TRUE(centres.ok()) << centres.status();
  KmeansOptions options;
  options.keep_first_assignment = true;
  absl::StatusOr<KmeansResult> full = RunLloydGpu(Context(), points, *centres, options);
  ASSERT_TRUE(full.ok()) << full.status();
  options.max_iterations = 1;
  absl::StatusOr<KmeansResult> one = RunLloydGpu(Context(), points, *centres, options);
  ASSERT_TRUE(one.ok()) << one.status();
  EXPECT_GT(full->iterations, 1u);
  EXPECT_EQ(full->first_labels, one->labels);
  EXPECT_EQ(full->first_inertia, one->inertia);  // bit for bit
}

TEST(RunLnKmeansGpu, CancelledRunsReturnCancelled) {
  const PointSet points = Blobs(2000, 3, 10, 6);
  const std::vector<ClusterId> seeds = Seeds(points, 12);
  const std::atomic<bool> cancel{true};
  LnKmeansOptions options;
  options.cancel = &cancel;
  EXPECT_EQ(RunLnKmeansGpu(Context(), points, seeds, options).status().code(),
            absl::StatusCode::kCancelled);
  KmeansOptions lloyd;
  lloyd.cancel = &cancel;
  absl::StatusOr<std::vector<float>> centres = RandomPointCentres(points, 12, 1);
  ASSERT_TRUE(centres.ok());
  EXPECT_EQ(RunLloydGpu(Context(), points, *centres, lloyd).status().code(),
            absl::StatusCode::kCancelled);
}

TEST(RunLnKmeansGpu, InjectedGlFailureNamesThePass) {
  const PointSet points = Blobs(2000, 3, 10, 5);
  const std::vector<ClusterId> seeds = Seeds(points, 12);
  ::mlclust::testing::ExpectGlFailureInPass(
      "ln-kmeans assign", [&] { return RunLnKmeansGpu(Context(), points, seeds); });
  EXPECT_TRUE(RunLnKmeansGpu(Context(), points, seeds).ok());
}

}  // namespace
}  // namespace mlclust::gpu
