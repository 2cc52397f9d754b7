#include "gpu/kernels/boundary_faces.h"

#include <gtest/gtest.h>

#include <random>
#include <thread>
#include <vector>

#include "core/mesh/mesh.h"
#include "gpu/context/gl_context.h"
#include "gpu/tools/test_meshes.h"
#include "tests/fixtures/gl_test_context.h"
#include "tests/fixtures/labels.h"
#include "tests/fixtures/test_meshes.h"

namespace mlclust::gpu {
namespace {

std::unique_ptr<GlContext> MakeContext(const GlContextOptions& options = {}) {
  return ::mlclust::testing::MakeGlContext(options);
}

using ::mlclust::testing::AdjacencyOf;

using ::mlclust::testing::AsLabels;

// Two triangles sharing the edge 0-2 of the unit square.
TriangleMesh TwoTriangles() {
  return {.positions = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0}, .indices = {0, 1, 2, 0, 2, 3}};
}

TriangleMesh Tetrahedron() {
  return {.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1},
          .indices = {0, 2, 1, 0, 1, 3, 1, 2, 3, 0, 3, 2}};
}

std::vector<uint8_t> Flags(GlContext& context, const FaceAdjacency& adjacency,
                           const std::vector<ClusterId>& labels) {
  absl::StatusOr<std::vector<uint8_t>> flags = FlagBoundaryFaces(context, adjacency, labels);
  EXPECT_TRUE(flags.ok()) << flags.status();
  return flags.ok() ? *std::move(flags) : std::vector<uint8_t>{};
}

TEST(GpuBoundaryFacesTest, TwoTriangles) {
  std::unique_ptr<GlContext> context = MakeContext();
  ASSERT_NE(context, nullptr);
  const FaceAdjacency adjacency = AdjacencyOf(TwoTriangles());
  EXPECT_EQ(Flags(*context, adjacency, AsLabels({5, 5})), (std::vector<uint8_t>{0, 0}));
  EXPECT_EQ(Flags(*context, adjacency, AsLabels({5, 6})), (std::vector<uint8_t>{1, 1}));
  // Invalid() is a label like any other.
  EXPECT_EQ(Flags(*context, adjacency, {ClusterId::Invalid(), ClusterId(0)}),
            (std::vector<uint8_t>{1, 1}));
  EXPECT_EQ(FlagBoundaryFacesCpu(adjacency, AsLabels({5, 6})), (std::vector<uint8_t>{1, 1}));
}

TEST(GpuBoundaryFacesTest, Tetrahedron) {
  std::unique_ptr<GlContext> context = MakeContext();
  ASSERT_NE(context, nullptr);
  const FaceAdjacency adjacency = AdjacencyOf(Tetrahedron());
  // One cluster: a closed surface with no boundary at all.
  EXPECT_EQ(Flags(*context, adjacency, AsLabels({3, 3, 3, 3})), (std::vector<uint8_t>{0, 0, 0, 0}));
  // Every face touches every other, so one face apart makes all four boundary faces.
  EXPECT_EQ(Flags(*context, adjacency, AsLabels({3, 3, 9, 3})), (std::vector<uint8_t>{1, 1, 1, 1}));
  EXPECT_EQ(FlagBoundaryFacesCpu(adjacency, AsLabels({3, 3, 3, 3})),
            (std::vector<uint8_t>{0, 0, 0, 0}));
}

TEST(GpuBoundaryFacesTest, EmptyInputGivesEmptyFlags) {
  std::unique_ptr<GlContext> context = MakeContext();
  ASSERT_NE(context, nullptr);
  absl::StatusOr<std::vector<uint8_t>> flags = FlagBoundaryFaces(*context, FaceAdjacency{}, {});
  ASSERT_TRUE(flags.ok()) << flags.status();
  EXPECT_TRUE(flags->empty());
}

TEST(GpuBoundaryFacesTest, RejectsInconsistentInput) {
  std::unique_ptr<GlContext> context = MakeContext();
  ASSERT_NE(context, nullptr);
  FaceAdjacency adjacency = AdjacencyOf(TwoTriangles());
  EXPECT_EQ(FlagBoundaryFaces(*context, adjacency, AsLabels({1})).status().code(),
            absl::StatusCode::kInvalidArgument);
  adjacency.neighbours[1][2] = FaceId(2);  // only faces 0 and 1 exist
  const absl::Status status = FlagBoundaryFaces(*context, adjacency, AsLabels({1, 1})).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(status.message().find("face 1 edge 2"), absl::string_view::npos) << status;
}

TEST(GpuBoundaryFacesTest, UseFromAnotherThreadIsAFailedPrecondition) {
  std::unique_ptr<GlContext> context = MakeContext();
  ASSERT_NE(context, nullptr);
  const FaceAdjacency adjacency = AdjacencyOf(TwoTriangles());
  absl::Status status;
  std::thread([&] {
    status = FlagBoundaryFaces(*context, adjacency, AsLabels({1, 2})).status();
  }).join();
  EXPECT_EQ(status.code(), absl::StatusCode::kFailedPrecondition) << status;
}

// ~100k faces with block labels (long boundaries) and with random labels (almost every
// face on a boundary): the GPU equals the CPU face for face.
TEST(GpuBoundaryFacesTest, LargeGridMatchesCpu) {
  std::unique_ptr<GlContext> context = MakeContext();
  ASSERT_NE(context, nullptr);
  constexpr uint32_t kRows = 200, kCols = 250;  // 100,000 faces
  const TriangleMesh mesh = testing::MakeJitteredGrid(kRows, kCols, 0.2f);
  const FaceAdjacency adjacency = AdjacencyOf(mesh);

  const std::vector<ClusterId> blocks = testing::GridBlockLabels(kRows, kCols, 7);
  const std::vector<uint8_t> block_flags = Flags(*context, adjacency, blocks);
  EXPECT_EQ(block_flags, FlagBoundaryFacesCpu(adjacency, blocks));
  size_t boundary = 0;
  for (uint8_t flag : block_flags) boundary += flag;
  EXPECT_GT(boundary, 0u);
  EXPECT_LT(boundary, block_flags.size());

  std::mt19937 random(7);
  std::vector<ClusterId> scattered(mesh.num_faces());
  for (ClusterId& label : scattered) label = ClusterId(random() % 3);
  EXPECT_EQ(Flags(*context, adjacency, scattered), FlagBoundaryFacesCpu(adjacency, scattered));
}

// A 3 x 3 grid of work groups and 4 KiB buffers: the kernel must split the faces into
// chunks and each chunk's dispatch into rows, and still match the CPU.
TEST(GpuBoundaryFacesTest, ChunkedTwoDimensionalDispatchMatchesCpu) {
  GlContextOptions options;
  options.max_groups_per_dimension = 3;
  options.max_storage_buffer_bytes = 4096;  // 341 faces of adjacency per chunk
  std::unique_ptr<GlContext> context = MakeContext(options);
  ASSERT_NE(context, nullptr);
  constexpr uint32_t kRows = 20, kCols = 25;  // 1,000 faces; labels take 4,000 bytes
  const TriangleMesh mesh = testing::MakeJitteredGrid(kRows, kCols, 0.2f);
  const FaceAdjacency adjacency = AdjacencyOf(mesh);
  const std::vector<ClusterId> labels = testing::GridBlockLabels(kRows, kCols, 3);
  EXPECT_EQ(Flags(*context, adjacency, labels), FlagBoundaryFacesCpu(adjacency, labels));

  GlContextOptions tiny_groups;
  tiny_groups.max_groups_per_dimension = 2;  // 2 x 2 groups x 256 x 4 faces per dispatch
  std::unique_ptr<GlContext> grid_context = MakeContext(tiny_groups);
  ASSERT_NE(grid_context, nullptr);
  constexpr uint32_t kBigRows = 100, kBigCols = 100;  // 20,000 faces: 5 dispatches
  const TriangleMesh big = testing::MakeJitteredGrid(kBigRows, kBigCols, 0.2f);
  const FaceAdjacency big_adjacency = AdjacencyOf(big);
  const std::vector<ClusterId> big_labels = testing::GridBlockLabels(kBigRows, kBigCols, 5);
  EXPECT_EQ(Flags(*grid_context, big_adjacency, big_labels),
            FlagBoundaryFacesCpu(big_adjacency, big_labels));
}

TEST(GpuBoundaryFacesTest, MemoryBoundCountsLabelsAndOneChunk) {
  std::unique_ptr<GlContext> context = MakeContext();
  ASSERT_NE(context, nullptr);
  // 4 faces: labels 16 + adjacency 48 + flags one word of 4.
  EXPECT_EQ(FlagBoundaryFacesMemoryBound(*context, 4), 68u);

  GlContextOptions options;
  options.max_storage_buffer_bytes = 4096;
  std::unique_ptr<GlContext> small = MakeContext(options);
  ASSERT_NE(small, nullptr);
  // 1,000 faces in chunks of 341: labels 4,000 + adjacency 4,092 + flags 344.
  EXPECT_EQ(FlagBoundaryFacesMemoryBound(*small, 1000), 4000u + 4092u + 344u);
}

TEST(GpuBoundaryFacesTest, LabelsPastTheBufferLimitAreResourceExhausted) {
  GlContextOptions options;
  options.max_storage_buffer_bytes = 4096;  // labels of at most 1,024 faces
  std::unique_ptr<GlContext> context = MakeContext(options);
  ASSERT_NE(context, nullptr);
  const TriangleMesh mesh = testing::MakeJitteredGrid(20, 30, 0.2f);  // 1,200 faces
  const FaceAdjacency adjacency = AdjacencyOf(mesh);
  const std::vector<ClusterId> labels(mesh.num_faces(), ClusterId(0));
  EXPECT_EQ(FlagBoundaryFaces(*context, adjacency, labels).status().code(),
            absl::StatusCode::kResourceExhausted);
}

}  // namespace
}  // namespace mlclust::gpu
