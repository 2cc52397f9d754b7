// mesh --out's writers by extension (client/clustered_mesh_file.h) on a tetrahedron.
#include "client/clustered_mesh_file.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <string>
#include <vector>

#include "core/io/mesh_io.h"
#include "tests/fixtures/files.h"
#include "tests/fixtures/test_meshes.h"

namespace mlclust::client {
namespace {

std::string TempPath(const std::string& name) {
  return ::testing::TempDir() + "/clustered_mesh_file_test_" + name;
}

TEST(ClusteredMeshFileTest, TheFormatFollowsTheExtension) {
  EXPECT_EQ(*ClusteredMeshFormatOf("--out", "a.ply"), ClusteredMeshFormat::kPly);
  EXPECT_EQ(*ClusteredMeshFormatOf("--out", "dir.v2/A.GLB"), ClusteredMeshFormat::kGltf);
  EXPECT_EQ(*ClusteredMeshFormatOf("--out", "a.gltf"), ClusteredMeshFormat::kGltf);
  EXPECT_EQ(*ClusteredMeshFormatOf("--out", "a.Obj"), ClusteredMeshFormat::kObj);
  EXPECT_EQ(ClusteredMeshFormatOf("--out", "a.stl").status().message(),
            "--out a.stl: cannot write '.stl' files (the format follows the extension: .ply, "
            ".glb, .gltf or .obj)");
  EXPECT_EQ(ClusteredMeshFormatOf("--out", "dir.v2/out").status().message(),
            "--out dir.v2/out: cannot write a file without extension (the format follows the "
            "extension: .ply, .glb, .gltf or .obj)");
}

TEST(ClusteredMeshFileTest, PlyOnlyUnderAPlyName) {
  EXPECT_TRUE(CheckClusteredMeshOutputs("x.obj", "x.ply").ok());
  EXPECT_TRUE(CheckClusteredMeshOutputs(std::nullopt, std::nullopt).ok());
  EXPECT_EQ(CheckClusteredMeshOutputs(std::nullopt, "out.glb").message(),
            "--ply out.glb: --ply writes a PLY file, which the name .glb would misname; give "
            "--out out.glb to write glTF (its format follows the extension), or a .ply name");
  EXPECT_EQ(CheckClusteredMeshOutputs(std::nullopt, "out.obj").message(),
            "--ply out.obj: --ply writes a PLY file, which the name .obj would misname; give "
            "--out out.obj to write OBJ (its format follows the extension), or a .ply name");
  EXPECT_EQ(CheckClusteredMeshOutputs(std::nullopt, "out.txt").code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(CheckClusteredMeshOutputs("out.stl", "out.ply").code(),
            absl::StatusCode::kInvalidArgument);
}

TEST(ClusteredMeshFileTest, ObjHasAGroupPerRunOfOneCluster) {
  const TriangleMesh tetrahedron = testing::Tetrahedron();
  const std::vector<ClusterId> labels = {ClusterId(3), ClusterId(3), ClusterId::Invalid(),
                                         ClusterId(3)};
  const std::string path = TempPath("groups.obj");
  ASSERT_TRUE(WriteClusteredMesh(path, tetrahedron, labels).ok());
  EXPECT_EQ(testing::ReadFileBytes(path),
            "# written by mlclust: 4 vertices, 4 faces, a group per cluster\n"
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n"
            "g cluster_3\nf 1 3 2\nf 1 2 4\n"
            "g unclustered\nf 2 3 4\n"
            "g cluster_3\nf 1 4 3\n");
  // The file reads back as the same faces in the same order.
  absl::StatusOr<TriangleMesh> read = ReadMeshFile(path);
  ASSERT_TRUE(read.ok()) << read.status();
  ASSERT_EQ(read->num_faces(), 4u);
  for (size_t f = 0; f < 4; ++f) {
    for (int c = 0; c < 3; ++c) {
      for (int x = 0; x < 3; ++x) {
        EXPECT_EQ(read->positions[3 * read->indices[3 * f + c] + x],
                  tetrahedron.positions[3 * tetrahedron.indices[3 * f + c] + x]);
      }
    }
  }
  std::remove(path.c_str());
}

TEST(ClusteredMeshFileTest, EveryExtensionWritesAndBadInputIsRefused) {
  const TriangleMesh tetrahedron = testing::Tetrahedron();
  const std::vector<ClusterId> labels = {ClusterId(0), ClusterId(1), ClusterId(1), ClusterId(2)};
  for (const char* name : {"t.ply", "t.glb", "t.gltf", "t.obj"}) {
    const std::string path = TempPath(name);
    ASSERT_TRUE(WriteClusteredMesh(path, tetrahedron, labels).ok()) << name;
    absl::StatusOr<TriangleMesh> read = ReadMeshFile(path);
    ASSERT_TRUE(read.ok()) << name << ": " << read.status();
    EXPECT_EQ(read->num_faces(), 4u) << name;
    std::remove(path.c_str());
  }
  EXPECT_EQ(WriteClusteredMesh(TempPath("t.stl"), tetrahedron, labels).code(),
            absl::StatusCode::kInvalidArgument);
  const std::vector<ClusterId> three(3, ClusterId(0));
  EXPECT_EQ(WriteClusteredObj(TempPath("short.obj"), tetrahedron, three).message(),
            TempPath("short.obj") + ": 3 labels for 4 faces (one per face is needed)");
  TriangleMesh broken = tetrahedron;
  broken.indices[5] = 9;
  EXPECT_EQ(WriteClusteredObj(TempPath("broken.obj"), broken, labels).message(),
            TempPath("broken.obj") + ": face 1 names vertex 9 of 4");
}

}  // namespace
}  // namespace mlclust::client
