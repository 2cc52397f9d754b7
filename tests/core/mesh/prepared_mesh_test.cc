// PrepareMesh / PrepareMeshFile: the one set-up path, and its cancellation.
#include "core/mesh/prepared_mesh.h"

#include <gtest/gtest.h>

#include <atomic>

#include "core/io/prepare_mesh.h"
#include "core/mesh/connectivity_guard.h"
#include "tests/fixtures/test_meshes.h"

namespace mlclust {
namespace {

TEST(PrepareMeshTest, GivesWhatTheStepsGiveOneByOne) {
  const TriangleMesh grid = testing::Grid(5, {7});
  absl::StatusOr<PreparedMesh> prepared = PrepareMesh(grid);
  ASSERT_TRUE(prepared.ok()) << prepared.status();
  EXPECT_EQ(prepared->mesh.indices, grid.indices);
  const FaceAdjacency adjacency = *BuildFaceAdjacency(grid);
  ASSERT_EQ(prepared->adjacency.num_faces(), adjacency.num_faces());
  for (size_t f = 0; f < adjacency.num_faces(); ++f) {
    EXPECT_EQ(prepared->adjacency.neighbours[f], adjacency.neighbours[f]) << f;
  }
  const FaceMeasures measures = ComputeFaceMeasures(grid);
  EXPECT_EQ(prepared->measures.area, measures.area);
}

TEST(PrepareMeshTest, RefusesWhatValidateMeshRefuses) {
  absl::StatusOr<PreparedMesh> prepared = PrepareMesh(testing::BowTie());
  EXPECT_EQ(prepared.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(prepared.status(), ValidateMesh(testing::BowTie()));
}

TEST(PrepareMeshTest, TakesItsMeasuresFromTheMeasuresFunction) {
  const TriangleMesh grid = testing::Grid(4);
  std::atomic<bool> cancel{false};
  int calls = 0;
  PrepareMeshOptions options;
  options.cancel = &cancel;
  // Another device's measures: here the CPU's with every area doubled, so they can be told
  // apart from PrepareMesh's own.
  options.measure_faces = [&](const TriangleMesh& mesh,
                              const std::atomic<bool>* flag) -> absl::StatusOr<FaceMeasures> {
    ++calls;
    EXPECT_EQ(flag, &cancel);
    EXPECT_EQ(mesh.indices, grid.indices);
    FaceMeasures measures = ComputeFaceMeasures(mesh);
    for (double& area : measures.area) area *= 2;
    return measures;
  };
  absl::StatusOr<PreparedMesh> prepared = PrepareMesh(grid, options);
  ASSERT_TRUE(prepared.ok()) << prepared.status();
  EXPECT_EQ(calls, 1);
  const FaceMeasures cpu = ComputeFaceMeasures(grid);
  ASSERT_EQ(prepared->measures.num_faces(), cpu.num_faces());
  for (size_t f = 0; f < cpu.num_faces(); ++f) {
    EXPECT_EQ(prepared->measures.area[f], 2 * cpu.area[f]) << f;
  }
  EXPECT_EQ(prepared->adjacency.num_faces(), grid.num_faces());
}

TEST(PrepareMeshTest, ReturnsTheMeasuresFunctionsErrorAndChecksItsSize) {
  const TriangleMesh grid = testing::Grid(3);
  PrepareMeshOptions options;
  options.measure_faces = [](const TriangleMesh& /*mesh*/,
                             const std::atomic<bool>* /*cancel*/) -> absl::StatusOr<FaceMeasures> {
    return absl::UnavailableError("no GPU today");
  };
  EXPECT_EQ(PrepareMesh(grid, options).status(), absl::UnavailableError("no GPU today"));
  // Not called for a mesh that fails validation: ValidateMesh's error comes first.
  EXPECT_EQ(PrepareMesh(testing::BowTie(), options).status(), ValidateMesh(testing::BowTie()));
  options.measure_faces = [](const TriangleMesh& mesh,
                             const std::atomic<bool>* /*cancel*/) -> absl::StatusOr<FaceMeasures> {
    FaceMeasures measures = ComputeFaceMeasures(mesh);
    measures.unit_normal.pop_back();
    return measures;
  };
  EXPECT_EQ(PrepareMesh(grid, options).status().code(), absl::StatusCode::kInternal);
}

TEST(PrepareMeshTest, ReadsAFile) {
  absl::StatusOr<PreparedMesh> prepared = PrepareMeshFile(testing::DataPath("fandisk.off"));
  ASSERT_TRUE(prepared.ok()) << prepared.status();
  EXPECT_EQ(prepared->mesh.num_faces(), 12946u);
  EXPECT_EQ(prepared->adjacency.num_faces(), 12946u);
  EXPECT_EQ(prepared->measures.num_faces(), 12946u);
  EXPECT_EQ(PrepareMeshFile(testing::DataPath("no-such-mesh.off")).status().code(),
            absl::StatusCode::kNotFound);
}

TEST(SetUpCancellationTest, ASetFlagReturnsCancelledFromEveryStep) {
  const TriangleMesh grid = testing::Grid(8);
  std::atomic<bool> cancel{true};
  EXPECT_EQ(ValidateMesh(grid, &cancel).code(), absl::StatusCode::kCancelled);
  EXPECT_EQ(BuildFaceAdjacency(grid, &cancel).status().code(), absl::StatusCode::kCancelled);
  EXPECT_EQ(PrepareMesh(grid, {&cancel}).status().code(), absl::StatusCode::kCancelled);
  EXPECT_EQ(PrepareMeshFile(testing::DataPath("fandisk.off"), {&cancel}).status().code(),
            absl::StatusCode::kCancelled);
  const FaceAdjacency adjacency = *BuildFaceAdjacency(grid);
  EXPECT_EQ(ConnectivityGuard::Build(grid, adjacency, &cancel).status().code(),
            absl::StatusCode::kCancelled);
  // A clear flag changes nothing.
  cancel = false;
  EXPECT_TRUE(ValidateMesh(grid, &cancel).ok());
  EXPECT_TRUE(PrepareMesh(grid, {&cancel}).ok());
  EXPECT_TRUE(ConnectivityGuard::Build(grid, adjacency, &cancel).ok());
}

}  // namespace
}  // namespace mlclust
