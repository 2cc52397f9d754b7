#include "gpu/kernels/face_measures_gpu.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/mesh/face_measures.h"
#include "core/mesh/mesh.h"
#include "gpu/context/gl_context.h"
#include "gpu/tools/test_meshes.h"
#include "tests/fixtures/gl_test_context.h"

namespace mlclust::gpu {
namespace {

// The parity contract of ComputeFaceMeasuresGpu (see its header): a driver may round
// division and sqrt differently from IEEE, so allow 1e-12 relative; llvmpipe is exact.
constexpr double kRelativeTolerance = 1e-12;

std::unique_ptr<GlContext> MakeContext(const GlContextOptions& options = {}) {
  return ::mlclust::testing::MakeGlContext(options);
}

double RelativeDifference(double gpu, double cpu) {
  return std::abs(gpu - cpu) / std::max(std::abs(cpu), 1e-300);
}

// Largest component difference relative to the CPU vector's length (a component near
// zero is measured against the whole vector, not against itself).
double RelativeDifference(const Vec3& gpu, const Vec3& cpu) {
  const double difference =
      std::max({std::abs(gpu.x - cpu.x), std::abs(gpu.y - cpu.y), std::abs(gpu.z - cpu.z)});
  return difference == 0 ? 0 : difference / std::max(Norm(cpu), 1e-300);
}

struct Parity {
  double area = 0, centroid = 0, normal = 0;
  size_t identical_faces = 0;
};

Parity CompareToCpu(const FaceMeasures& gpu, const FaceMeasures& cpu) {
  Parity parity;
  EXPECT_EQ(gpu.num_faces(), cpu.num_faces());
  EXPECT_EQ(gpu.centroid.size(), cpu.num_faces());
  EXPECT_EQ(gpu.unit_normal.size(), cpu.num_faces());
  if (gpu.num_faces() != cpu.num_faces()) return parity;
  for (size_t i = 0; i < cpu.num_faces(); ++i) {
    const double area = RelativeDifference(gpu.area[i], cpu.area[i]);
    const double centroid = RelativeDifference(gpu.centroid[i], cpu.centroid[i]);
    const double normal = RelativeDifference(gpu.unit_normal[i], cpu.unit_normal[i]);
    parity.area = std::max(parity.area, area);
    parity.centroid = std::max(parity.centroid, centroid);
    parity.normal = std::max(parity.normal, normal);
    parity.identical_faces += area == 0 && centroid == 0 && normal == 0;
  }
  return parity;
}

void ExpectParity(GlContext& context, const TriangleMesh& mesh, const char* name) {
  absl::StatusOr<FaceMeasures> gpu = ComputeFaceMeasuresGpu(context, mesh);
  ASSERT_TRUE(gpu.ok()) << gpu.status();
  const Parity parity = CompareToCpu(*gpu, ComputeFaceMeasures(mesh));
  std::printf(
      "%s, %zu faces on %s: max relative difference area %.3g, centroid %.3g, "
      "normal %.3g; %zu faces bit-identical\n",
      name, mesh.num_faces(), context.renderer().c_str(), parity.area, parity.centroid,
      parity.normal, parity.identical_faces);
  EXPECT_LE(parity.area, kRelativeTolerance);
  EXPECT_LE(parity.centroid, kRelativeTolerance);
  EXPECT_LE(parity.normal, kRelativeTolerance);
}

TEST(GpuFaceMeasuresTest, RightTriangle) {
  std::unique_ptr<GlContext> context = MakeContext();
  ASSERT_NE(context, nullptr);
  const TriangleMesh mesh = {.positions = {0, 0, 0, 2, 0, 0, 0, 2, 0}, .indices = {0, 1, 2}};
  absl::StatusOr<FaceMeasures> measures = ComputeFaceMeasuresGpu(*context, mesh);
  ASSERT_TRUE(measures.ok()) << measures.status();
  ASSERT_EQ(measures->num_faces(), 1u);
  EXPECT_EQ(measures->area[0], 2.0);
  EXPECT_DOUBLE_EQ(measures->centroid[0].x, 2.0 / 3.0);
  EXPECT_DOUBLE_EQ(measures->centroid[0].y, 2.0 / 3.0);
  EXPECT_EQ(measures->centroid[0].z, 0.0);
  EXPECT_EQ(measures->unit_normal[0].x, 0.0);
  EXPECT_EQ(measures->unit_normal[0].y, 0.0);
  EXPECT_EQ(measures->unit_normal[0].z, 1.0);  // counter-clockwise seen from +z
}

// Three distinct but collinear vertices: area 0 and a zero normal, as on the CPU.
TEST(GpuFaceMeasuresTest, ZeroAreaFaceHasZeroNormal) {
  std::unique_ptr<GlContext> context = MakeContext();
  ASSERT_NE(context, nullptr);
  const TriangleMesh mesh = {.positions = {0, 0, 0, 1, 1, 1, 2, 2, 2}, .indices = {0, 1, 2}};
  absl::StatusOr<FaceMeasures> measures = ComputeFaceMeasuresGpu(*context, mesh);
  ASSERT_TRUE(measures.ok()) << measures.status();
  EXPECT_EQ(measures->area[0], 0.0);
  EXPECT_EQ(measures->unit_normal[0].x, 0.0);
  EXPECT_EQ(measures->unit_normal[0].y, 0.0);
  EXPECT_EQ(measures->unit_normal[0].z, 0.0);
  EXPECT_EQ(measures->centroid[0].x, 1.0);
}

TEST(GpuFaceMeasuresTest, EmptyMeshGivesNoMeasures) {
  std::unique_ptr<GlContext> context = MakeContext();
  ASSERT_NE(context, nullptr);
  absl::StatusOr<FaceMeasures> measures = ComputeFaceMeasuresGpu(*context, TriangleMesh{});
  ASSERT_TRUE(measures.ok()) << measures.status();
  EXPECT_EQ(measures->num_faces(), 0u);
}

TEST(GpuFaceMeasuresTest, RejectsWhatTheShaderWouldReadOutOfBounds) {
  std::unique_ptr<GlContext> context = MakeContext();
  ASSERT_NE(context, nullptr);
  const TriangleMesh bad_index = {.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0}, .indices = {0, 1, 3}};
  const absl::Status status = ComputeFaceMeasuresGpu(*context, bad_index).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(status.message().find("face 0 corner 2"), absl::string_view::npos) << status;

  const TriangleMesh partial_vertex = {.positions = {0, 0, 0, 1, 0, 0, 0, 1}, .indices = {0, 1, 2}};
  EXPECT_EQ(ComputeFaceMeasuresGpu(*context, partial_vertex).status().code(),
            absl::StatusCode::kInvalidArgument);
  const TriangleMesh partial_face = {.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0}, .indices = {0, 1}};
  EXPECT_EQ(ComputeFaceMeasuresGpu(*context, partial_face).status().code(),
            absl::StatusCode::kInvalidArgument);
}

// 81,920 faces of a sphere off the origin (centroids far from zero relative to the faces'
// size, normals in every direction).
TEST(GpuFaceMeasuresTest, IcosphereMatchesCpu) {
  std::unique_ptr<GlContext> context = MakeContext();
  ASSERT_NE(context, nullptr);
  ExpectParity(*context, testing::MakeIcosphere(6, 3.5, 10.0, -4.0, 2.5), "icosphere");
}

// 100,352 faces of a grid jittered by 0.3 in x, y and z.
TEST(GpuFaceMeasuresTest, JitteredGridMatchesCpu) {
  std::unique_ptr<GlContext> context = MakeContext();
  ASSERT_NE(context, nullptr);
  ExpectParity(*context, testing::MakeJitteredGrid(224, 224, 0.3f), "jittered grid");
}

// A 2 x 2 grid of work groups and 64 KiB buffers: faces in chunks of 2,048 (the dispatch
// bound), each dispatch in rows, still equal to the CPU.
TEST(GpuFaceMeasuresTest, ChunkedTwoDimensionalDispatchMatchesCpu) {
  GlContextOptions options;
  options.max_groups_per_dimension = 2;
  options.max_storage_buffer_bytes = 1 << 16;
  std::unique_ptr<GlContext> context = MakeContext(options);
  ASSERT_NE(context, nullptr);
  ExpectParity(*context, testing::MakeJitteredGrid(60, 70, 0.3f), "chunked grid");
}

TEST(GpuFaceMeasuresTest, MemoryBoundCountsPositionsAndOneChunk) {
  std::unique_ptr<GlContext> context = MakeContext();
  ASSERT_NE(context, nullptr);
  // One face, three vertices: positions 36 + indices 12 + area 8 + centroid 24 + normal 24.
  EXPECT_EQ(ComputeFaceMeasuresGpuMemoryBound(*context, 1, 3), 104u);
}

TEST(GpuFaceMeasuresTest, PositionsPastTheBufferLimitAreResourceExhausted) {
  GlContextOptions options;
  options.max_storage_buffer_bytes = 4096;  // 341 vertices
  std::unique_ptr<GlContext> context = MakeContext(options);
  ASSERT_NE(context, nullptr);
  EXPECT_EQ(
      ComputeFaceMeasuresGpu(*context, testing::MakeJitteredGrid(20, 20, 0.1f)).status().code(),
      absl::StatusCode::kResourceExhausted);
}

}  // namespace
}  // namespace mlclust::gpu
