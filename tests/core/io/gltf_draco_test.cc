#include "core/io/gltf_draco.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <random>
#include <string>

#include "absl/strings/str_cat.h"
#include "core/io/draco_codec.h"
#include "tests/fixtures/test_meshes.h"

namespace mlclust {
namespace {

using testing::Grid;
using ::testing::HasSubstr;

absl::StatusOr<std::string> NoFiles(const std::string& uri) {
  return absl::NotFoundError(absl::StrCat("no file ", uri));
}

// A GLB with one Draco-compressed primitive of a 3 x 3 grid.
std::string DracoGlb() {
  absl::StatusOr<std::string> draco = EncodeMeshToDraco(Grid(3));
  EXPECT_TRUE(draco.ok());
  const std::string json = absl::StrCat(
      R"({"asset":{"version":"2.0"},"extensionsUsed":["KHR_draco_mesh_compression"],)",
      R"("scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],"meshes":[{"primitives":[)",
      R"({"attributes":{"POSITION":0},"indices":1,"extensions":{"KHR_draco_mesh_compression":)",
      R"({"bufferView":0,"attributes":{"POSITION":0}}}}]}],"accessors":[{"componentType":5126,)",
      R"("count":16,"type":"VEC3"},{"componentType":5125,"count":54,"type":"SCALAR"}],)",
      R"("bufferViews":[{"buffer":0,"byteLength":)", draco->size(), R"(}],"buffers":[)",
      R"({"byteLength":)", draco->size(), "}]}");
  absl::StatusOr<std::string> glb = PackGlb(json, *draco);
  EXPECT_TRUE(glb.ok());
  return *glb;
}

TEST(GltfDracoTest, DecompressedGlbHasNoDracoLeft) {
  const std::string glb = DracoGlb();
  EXPECT_TRUE(GltfUsesDraco(glb));
  absl::StatusOr<std::string> plain = DecompressDracoGltf(glb, NoFiles);
  ASSERT_TRUE(plain.ok()) << plain.status();
  EXPECT_FALSE(GltfUsesDraco(*plain));
  EXPECT_EQ(plain->size() % 4, 0u);
  EXPECT_TRUE(plain->starts_with("glTF"));
}

TEST(GltfDracoTest, PlainGltfIsNotTouched) {
  EXPECT_FALSE(GltfUsesDraco(R"({"asset":{"version":"2.0"}})"));
  EXPECT_FALSE(GltfUsesDraco("not glTF at all"));
}

TEST(GltfDracoTest, RefusesEveryTruncation) {
  const std::string glb = DracoGlb();
  for (size_t length = 0; length < glb.size(); ++length) {
    absl::StatusOr<std::string> plain = DecompressDracoGltf(glb.substr(0, length), NoFiles);
    if (!plain.ok()) EXPECT_EQ(plain.status().code(), absl::StatusCode::kInvalidArgument);
  }
}

TEST(GltfDracoTest, SurvivesCorruptedBytes) {
  const std::string glb = DracoGlb();
  std::mt19937 random(11);
  size_t refused = 0;
  for (int i = 0; i < 3000; ++i) {
    std::string bytes = glb;
    for (int k = 0; k < 1 + i % 4; ++k) {
      bytes[std::uniform_int_distribution<size_t>(0, bytes.size() - 1)(random)] =
          static_cast<char>(random());
    }
    absl::StatusOr<std::string> plain = DecompressDracoGltf(bytes, NoFiles);
    if (!plain.ok()) {
      EXPECT_EQ(plain.status().code(), absl::StatusCode::kInvalidArgument);
      ++refused;
    }
  }
  EXPECT_GT(refused, 0u);
}

TEST(GltfDracoTest, RefusesAMissingBufferAndABadDataUri) {
  absl::StatusOr<std::string> plain = DecompressDracoGltf(
      R"({"buffers":[{"byteLength":4,"uri":"no-such.bin"}],"meshes":[]})", NoFiles);
  EXPECT_EQ(plain.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(plain.status().message()),
              HasSubstr("buffer 0 (no-such.bin): no file no-such.bin"));
  // A buffer file shorter than its byteLength.
  plain = DecompressDracoGltf(R"({"buffers":[{"byteLength":4,"uri":"a.bin"}]})",
                              [](const std::string&) { return std::string("ab"); });
  EXPECT_THAT(std::string(plain.status().message()), HasSubstr("holds 2 bytes, byteLength says 4"));
  plain = DecompressDracoGltf(R"({"buffers":[{"byteLength":4,"uri":"data:,abcd"}]})", NoFiles);
  EXPECT_EQ(plain.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(plain.status().message()), HasSubstr("not base64"));
  plain = DecompressDracoGltf(R"({"buffers":[{"byteLength":4}]})", NoFiles);
  EXPECT_THAT(std::string(plain.status().message()), HasSubstr("no GLB BIN chunk"));
  plain = DecompressDracoGltf("{not json", NoFiles);
  EXPECT_THAT(std::string(plain.status().message()), HasSubstr("does not parse"));
}

}  // namespace
}  // namespace mlclust
