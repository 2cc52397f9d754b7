#include "core/io/draco_peek.h"

#include <filesystem>
#include <string>

#include "core/io/allocation_budget.h"
#include "core/io/draco_codec.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "tests/fixtures/files.h"
#include "tests/fixtures/test_meshes.h"

namespace mlclust {
namespace {

using ::testing::HasSubstr;

TEST(DracoPeekTest, EdgebreakerWithFaceIdsIsNamed) {
  DracoEncodeOptions options;
  options.method = DracoMethod::kEdgebreaker;
  options.write_face_ids = true;
  absl::StatusOr<std::string> bytes = EncodeMeshToDraco(testing::MakeCube(2).mesh, options);
  ASSERT_TRUE(bytes.ok()) << bytes.status();
  const DracoPayloadFacts facts = PeekDracoPayload(*bytes);
  EXPECT_TRUE(facts.is_draco);
  EXPECT_TRUE(facts.is_mesh);
  EXPECT_EQ(facts.method, "edgebreaker");
  EXPECT_TRUE(facts.names_face_ids);
  EXPECT_THAT(DescribeFaceOrder(facts), HasSubstr(kDracoFaceIdAttributeName));
}

TEST(DracoPeekTest, SequentialAndEdgebreakerWithoutIds) {
  for (DracoMethod method : {DracoMethod::kSequential, DracoMethod::kEdgebreaker}) {
    DracoEncodeOptions options;
    options.method = method;
    absl::StatusOr<std::string> bytes = EncodeMeshToDraco(testing::MakeCube(2).mesh, options);
    ASSERT_TRUE(bytes.ok()) << bytes.status();
    const DracoPayloadFacts facts = PeekDracoPayload(*bytes);
    EXPECT_TRUE(facts.is_mesh);
    EXPECT_FALSE(facts.names_face_ids);
    EXPECT_EQ(facts.method, method == DracoMethod::kSequential ? "sequential" : "edgebreaker");
    EXPECT_THAT(DescribeFaceOrder(facts),
                HasSubstr(method == DracoMethod::kSequential ? "keeps the encoder's face order"
                                                             : "reorders faces"));
  }
}

TEST(DracoPeekTest, NotDraco) {
  for (const std::string& bytes : {std::string(), std::string("DRAC"), std::string(100, 'x')}) {
    const DracoPayloadFacts facts = PeekDracoPayload(bytes);
    EXPECT_FALSE(facts.is_draco);
    EXPECT_FALSE(facts.names_face_ids);
    EXPECT_EQ(DescribeFaceOrder(facts), "");
  }
}

// A header whose metadata declares a 4 GiB entry the payload does not hold: read as naming
// no face ids, with next to nothing allocated. (Draco 1.5.5's metadata decoder checks an
// entry's size against the bytes left, so the peek's allocation budget is a backstop that
// this payload does not reach.)
TEST(DracoPeekTest, MetadataDeclaringMoreThanThePayloadHoldsNamesNoFaceIds) {
  std::string bytes = "DRACO";
  bytes += static_cast<char>(2);  // version 2.2
  bytes += static_cast<char>(2);
  bytes += static_cast<char>(1);        // triangular mesh
  bytes += static_cast<char>(1);        // edgebreaker
  bytes += std::string("\x00\x80", 2);  // flags: metadata
  bytes += static_cast<char>(1);        // one attribute metadata
  bytes += static_cast<char>(0);        // for attribute 0
  bytes += static_cast<char>(1);        // one entry
  bytes += static_cast<char>(4);        // its name: "name"
  bytes += "name";
  bytes += std::string("\xf0\xff\xff\xff\x0f", 5);  // its size: 0xfffffff0 bytes
  bytes += "mlclust_face_id";
  ScopedAllocationBudget outer(size_t{64} << 20);
  const DracoPayloadFacts facts = PeekDracoPayload(bytes);
  EXPECT_TRUE(facts.is_draco);
  EXPECT_FALSE(facts.names_face_ids);
  EXPECT_LT(outer.allocated_bytes(), size_t{8} << 20);
  EXPECT_FALSE(outer.exceeded());
}

// The fuzz corpus (fuzz/corpus/draco): what the peek says at acceptance holds for every
// payload the decoder accepts, as fuzz_draco checks on random bytes.
TEST(DracoPeekTest, AgreesWithTheDecoderOnTheFuzzCorpus) {
  const std::filesystem::path corpus = std::filesystem::path(testing::FuzzSeedPath("draco"));
  int files = 0, decoded_with_ids = 0;
  for (const auto& entry : std::filesystem::directory_iterator(corpus)) {
    const std::string bytes = testing::ReadFileBytes(entry.path().string());
    const DracoPayloadFacts facts = PeekDracoPayload(bytes);
    absl::StatusOr<DecodedDracoMesh> decoded = DecodeDracoMeshWithFaceIds(bytes);
    ++files;
    if (!decoded.ok()) continue;
    EXPECT_TRUE(facts.is_draco && facts.is_mesh) << entry.path();
    EXPECT_EQ(facts.names_face_ids, decoded->has_face_ids) << entry.path();
    decoded_with_ids += decoded->has_face_ids ? 1 : 0;
  }
  EXPECT_GE(files, 5);
  EXPECT_GE(decoded_with_ids, 1);  // grid_edgebreaker_face_ids.drc
}

}  // namespace
}  // namespace mlclust
