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
