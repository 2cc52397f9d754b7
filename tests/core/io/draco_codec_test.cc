#include "core/io/draco_codec.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <iostream>
#include <limits>
#include <memory>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/io/allocation_budget.h"
#include "core/io/mesh_io.h"
#include "core/mesh/mesh.h"
#include "draco/attributes/geometry_attribute.h"
#include "draco/compression/config/compression_shared.h"
#include "draco/compression/expert_encode.h"
#include "draco/core/encoder_buffer.h"
#include "draco/mesh/mesh.h"
#include "draco/metadata/geometry_metadata.h"
#include "draco/point_cloud/point_cloud.h"
#include "tests/fixtures/files.h"
#include "tests/fixtures/foreign_draco.h"
#include "tests/fixtures/test_meshes.h"

namespace mlclust {
namespace {

using testing::DataPath;
using testing::EncodeLikeForeignEncoder;
using testing::Grid;
using ::testing::HasSubstr;
using testing::MakeMesh;
using testing::ReadFuzzSeed;
using testing::Tetrahedron;

std::string Message(const absl::Status& status) { return std::string(status.message()); }

TriangleMesh Fandisk() {
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(DataPath("fandisk.off"));
  EXPECT_TRUE(mesh.ok()) << mesh.status();
  return mesh.ok() ? *std::move(mesh) : TriangleMesh();
}

bool SameBits(const std::vector<float>& a, const std::vector<float>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0;
}

absl::StatusOr<TriangleMesh> RoundTrip(const TriangleMesh& mesh,
                                       const DracoEncodeOptions& options = {}) {
  absl::StatusOr<std::string> bytes = EncodeMeshToDraco(mesh, options);
  if (!bytes.ok()) return bytes.status();
  return DecodeDracoMesh(*bytes);
}

// Encodes with Draco directly (for methods and geometry EncodeMeshToDraco never makes).
std::string EncodeWithDraco(const TriangleMesh& mesh, int method, int quantization_bits) {
  draco::Mesh draco_mesh;
  draco_mesh.set_num_points(static_cast<uint32_t>(mesh.num_vertices()));
  draco::GeometryAttribute position;
  position.Init(draco::GeometryAttribute::POSITION, nullptr, 3, draco::DT_FLOAT32, false,
                sizeof(float) * 3, 0);
  const int id = draco_mesh.AddAttribute(position, true, mesh.num_vertices());
  for (uint32_t v = 0; v < mesh.num_vertices(); ++v) {
    draco_mesh.attribute(id)->SetAttributeValue(draco::AttributeValueIndex(v),
                                                &mesh.positions[3 * v]);
  }
  for (size_t f = 0; f < mesh.num_faces(); ++f) {
    draco_mesh.AddFace({draco::PointIndex(mesh.indices[3 * f]),
                        draco::PointIndex(mesh.indices[3 * f + 1]),
                        draco::PointIndex(mesh.indices[3 * f + 2])});
  }
  draco::ExpertEncoder encoder(draco_mesh);
  encoder.SetEncodingMethod(method);
  if (quantization_bits > 0) encoder.SetAttributeQuantization(id, quantization_bits);
  draco::EncoderBuffer buffer;
  EXPECT_TRUE(encoder.EncodeToBuffer(&buffer).ok());
  return std::string(buffer.data(), buffer.size());
}

// ---------------------------------------------------------------------------------------
// Round trips.

TEST(DracoCodecTest, FandiskRoundTripIsBitExact) {
  const TriangleMesh fandisk = Fandisk();
  ASSERT_EQ(fandisk.num_faces(), 12946u);
  absl::StatusOr<TriangleMesh> decoded = RoundTrip(fandisk);
  ASSERT_TRUE(decoded.ok()) << decoded.status();
  EXPECT_EQ(decoded->num_vertices(), 6475u);  // No deduplication, no reordering.
  EXPECT_TRUE(SameBits(decoded->positions, fandisk.positions));
  EXPECT_EQ(decoded->indices, fandisk.indices);
}

TEST(DracoCodecTest, BytesAfterTheDracoDataAreRefused) {
  const TriangleMesh fandisk = Fandisk();
  for (DracoMethod method : {DracoMethod::kSequential, DracoMethod::kEdgebreaker}) {
    DracoEncodeOptions options;
    options.method = method;
    options.write_face_ids = method == DracoMethod::kEdgebreaker;
    absl::StatusOr<std::string> bytes = EncodeMeshToDraco(fandisk, options);
    ASSERT_TRUE(bytes.ok()) << bytes.status();
    ASSERT_TRUE(DecodeDracoMeshWithFaceIds(*bytes).ok());  // the whole payload is read
    const absl::StatusOr<DecodedDracoMesh> joined = DecodeDracoMeshWithFaceIds(*bytes + "xyz");
    EXPECT_EQ(joined.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_EQ(joined.status().message(),
              absl::StrCat("Draco mesh: 3 bytes after the end of the Draco data (it ends at byte ",
                           bytes->size(), " of ", bytes->size() + 3, "); send one Draco mesh"));
    EXPECT_EQ(DecodeDracoMeshWithFaceIds(*bytes + *bytes).status().code(),
              absl::StatusCode::kInvalidArgument);
  }
}

TEST(DracoCodecTest, EverySpeedIsLossless) {
  const TriangleMesh fandisk = Fandisk();
  for (int speed : {0, 5, 10}) {
    DracoEncodeOptions options;
    options.speed = speed;
    absl::StatusOr<TriangleMesh> decoded = RoundTrip(fandisk, options);
    ASSERT_TRUE(decoded.ok()) << "speed " << speed << ": " << decoded.status();
    EXPECT_TRUE(SameBits(decoded->positions, fandisk.positions)) << "speed " << speed;
    EXPECT_EQ(decoded->indices, fandisk.indices) << "speed " << speed;
  }
}

TEST(DracoCodecTest, ShuffledFacesComeBackInTheirShuffledOrder) {
  TriangleMesh shuffled = Fandisk();
  std::vector<uint32_t> order(shuffled.num_faces());
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), std::mt19937(42));
  std::vector<uint32_t> indices(shuffled.indices.size());
  for (size_t k = 0; k < order.size(); ++k) {
    std::copy_n(&shuffled.indices[3 * order[k]], 3, &indices[3 * k]);
  }
  shuffled.indices = indices;
  absl::StatusOr<TriangleMesh> decoded = RoundTrip(shuffled);
  ASSERT_TRUE(decoded.ok()) << decoded.status();
  EXPECT_EQ(decoded->indices, shuffled.indices);
  EXPECT_TRUE(SameBits(decoded->positions, shuffled.positions));
}

TEST(DracoCodecTest, QuantizedIsSmallerAndWithinOneStep) {
  const TriangleMesh fandisk = Fandisk();
  absl::StatusOr<std::string> lossless = EncodeMeshToDraco(fandisk);
  DracoEncodeOptions options;
  options.position_quantization_bits = 14;
  absl::StatusOr<std::string> quantized = EncodeMeshToDraco(fandisk, options);
  ASSERT_TRUE(lossless.ok() && quantized.ok());
  EXPECT_LT(quantized->size(), lossless->size() * 3 / 4);

  absl::StatusOr<TriangleMesh> decoded = DecodeDracoMesh(*quantized);
  ASSERT_TRUE(decoded.ok()) << decoded.status();
  EXPECT_EQ(decoded->indices, fandisk.indices);
  ASSERT_EQ(decoded->positions.size(), fandisk.positions.size());
  // Draco quantizes all axes on one grid spanning the largest extent.
  float low[3], high[3];
  for (int a = 0; a < 3; ++a) {
    low[a] = std::numeric_limits<float>::max();
    high[a] = std::numeric_limits<float>::lowest();
  }
  for (size_t i = 0; i < fandisk.positions.size(); ++i) {
    low[i % 3] = std::min(low[i % 3], fandisk.positions[i]);
    high[i % 3] = std::max(high[i % 3], fandisk.positions[i]);
  }
  const float extent = std::max({high[0] - low[0], high[1] - low[1], high[2] - low[2]});
  const float step = extent / ((1 << 14) - 1);
  float worst = 0;
  for (size_t i = 0; i < fandisk.positions.size(); ++i) {
    worst = std::max(worst, std::abs(decoded->positions[i] - fandisk.positions[i]));
  }
  EXPECT_LE(worst, step) << "extent " << extent;
  EXPECT_GT(worst, 0) << "14 bits cannot be exact on fandisk";
}

TEST(DracoCodecTest, EncodedSizesOfFandisk) {
  // Recorded for the design notes; the assertions only pin the ordering.
  const TriangleMesh fandisk = Fandisk();
  DracoEncodeOptions q14;
  q14.position_quantization_bits = 14;
  const size_t lossless = EncodeMeshToDraco(fandisk)->size();
  const size_t quantized = EncodeMeshToDraco(fandisk, q14)->size();
  const size_t edgebreaker_lossless =
      EncodeWithDraco(fandisk, draco::MESH_EDGEBREAKER_ENCODING, 0).size();
  const size_t edgebreaker_q14 =
      EncodeWithDraco(fandisk, draco::MESH_EDGEBREAKER_ENCODING, 14).size();
  const size_t raw = fandisk.positions.size() * 4 + fandisk.indices.size() * 4;
  std::cout << "fandisk (" << fandisk.num_vertices() << " vertices, " << fandisk.num_faces()
            << " faces): raw arrays " << raw << " B, sequential lossless " << lossless
            << " B, sequential 14-bit " << quantized << " B, edgebreaker lossless "
            << edgebreaker_lossless << " B, edgebreaker 14-bit " << edgebreaker_q14 << " B\n";
  ::testing::Test::RecordProperty("sequential_lossless_bytes", static_cast<int>(lossless));
  ::testing::Test::RecordProperty("sequential_q14_bytes", static_cast<int>(quantized));
  ::testing::Test::RecordProperty("edgebreaker_q14_bytes", static_cast<int>(edgebreaker_q14));
  EXPECT_LT(lossless, raw);
  EXPECT_LT(quantized, lossless);
  EXPECT_LT(edgebreaker_q14, quantized);
}

TEST(DracoCodecTest, NothingIsCleanedUpOnTheWay) {
  // A degenerate face (vertex 0 twice), the same face twice, two vertices at one
  // position (1 and 4) and an unused vertex (5): all must reach ValidateMesh.
  const TriangleMesh mesh = MakeMesh({0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 0, 0, 7, 7, 7},
                                     {0, 2, 1, 0, 0, 3, 1, 2, 3, 1, 2, 3, 0, 4, 3});
  for (int bits : {0, 3}) {  // 3 bits over the extent 7: the integer grid, exact.
    DracoEncodeOptions options;
    options.position_quantization_bits = bits;
    absl::StatusOr<TriangleMesh> decoded = RoundTrip(mesh, options);
    ASSERT_TRUE(decoded.ok()) << decoded.status();
    EXPECT_EQ(decoded->indices, mesh.indices) << "bits " << bits;
    EXPECT_EQ(decoded->positions, mesh.positions) << "bits " << bits;
    const absl::Status validation = ValidateMesh(*decoded);
    EXPECT_EQ(validation.code(), absl::StatusCode::kInvalidArgument);
    EXPECT_THAT(Message(validation), HasSubstr("face 1"));
  }
}

TEST(DracoCodecTest, LosslessCarriesNanForValidationToName) {
  const TriangleMesh mesh =
      MakeMesh({0, 0, 0, 1, 0, 0, 0, 1, std::numeric_limits<float>::quiet_NaN()}, {0, 1, 2});
  absl::StatusOr<TriangleMesh> decoded = RoundTrip(mesh);
  ASSERT_TRUE(decoded.ok()) << decoded.status();
  EXPECT_TRUE(std::isnan(decoded->positions[8]));

  DracoEncodeOptions options;
  options.position_quantization_bits = 12;
  absl::StatusOr<std::string> quantized = EncodeMeshToDraco(mesh, options);
  EXPECT_EQ(quantized.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(Message(quantized.status()), HasSubstr("vertex 2 has a non-finite coordinate"));
}

TEST(DracoCodecTest, EncoderRefusesBadOptionsAndIndices) {
  DracoEncodeOptions options;
  options.position_quantization_bits = 31;
  EXPECT_THAT(Message(EncodeMeshToDraco(Tetrahedron(), options).status()),
              HasSubstr("position_quantization_bits"));
  options.position_quantization_bits = -1;
  EXPECT_EQ(EncodeMeshToDraco(Tetrahedron(), options).status().code(),
            absl::StatusCode::kInvalidArgument);
  options = {};
  options.speed = 11;
  EXPECT_THAT(Message(EncodeMeshToDraco(Tetrahedron(), options).status()),
              HasSubstr("speed must be 0..10, got 11"));

  TriangleMesh broken = Tetrahedron();
  broken.indices[7] = 4;
  EXPECT_THAT(
      Message(EncodeMeshToDraco(broken).status()),
      HasSubstr("face 2 corner 1: vertex index 4 is out of range (the mesh has 4 vertices)"));
  broken = Tetrahedron();
  broken.indices.pop_back();
  EXPECT_EQ(EncodeMeshToDraco(broken).status().code(), absl::StatusCode::kInvalidArgument);

  const TriangleMesh no_faces = MakeMesh({0, 0, 0, 1, 0, 0, 0, 1, 0}, {});
  EXPECT_THAT(Message(EncodeMeshToDraco(no_faces).status()), HasSubstr("no faces"));
}

TEST(DracoCodecTest, EdgebreakerBytesDecodeInTheirOwnOrder) {
  // Not what EncodeMeshToDraco makes, but a client may send it: all faces arrive, in
  // the order edgebreaker chose.
  const TriangleMesh fandisk = Fandisk();
  absl::StatusOr<TriangleMesh> decoded =
      DecodeDracoMesh(EncodeWithDraco(fandisk, draco::MESH_EDGEBREAKER_ENCODING, 0));
  ASSERT_TRUE(decoded.ok()) << decoded.status();
  EXPECT_EQ(decoded->num_faces(), fandisk.num_faces());
  EXPECT_EQ(decoded->num_vertices(), fandisk.num_vertices());
  EXPECT_NE(decoded->indices, fandisk.indices);
  EXPECT_TRUE(ValidateMesh(*decoded).ok());
}

// ---------------------------------------------------------------------------------------
// The per-face id attribute.

// The corners of face f of `mesh` as positions, starting at the corner with the smallest
// (x, y, z): edgebreaker keeps a face's winding but may start it at another corner.
std::array<std::array<float, 3>, 3> FaceCorners(const TriangleMesh& mesh, size_t f) {
  std::array<std::array<float, 3>, 3> corners;
  for (int c = 0; c < 3; ++c) {
    for (int k = 0; k < 3; ++k) corners[c][k] = mesh.positions[3 * mesh.indices[3 * f + c] + k];
  }
  const int first =
      static_cast<int>(std::min_element(corners.begin(), corners.end()) - corners.begin());
  std::rotate(corners.begin(), corners.begin() + first, corners.end());
  return corners;
}

// The number of faces f of `decoded` that are not face f of `original` (each coordinate
// within `tolerance`): 0 when labels computed on `decoded` apply to `original` as they are.
size_t FacesOutOfPlace(const TriangleMesh& original, const TriangleMesh& decoded, float tolerance) {
  EXPECT_EQ(decoded.num_faces(), original.num_faces());
  size_t wrong = 0;
  for (size_t f = 0; f < std::min(original.num_faces(), decoded.num_faces()); ++f) {
    const auto want = FaceCorners(original, f);
    // Quantisation may change which corner is smallest: try the three rotations.
    bool same = false;
    for (int r = 0; r < 3 && !same; ++r) {
      auto got = FaceCorners(decoded, f);
      std::rotate(got.begin(), got.begin() + r, got.end());
      same = true;
      for (int c = 0; c < 3; ++c) {
        for (int k = 0; k < 3; ++k) same &= std::abs(got[c][k] - want[c][k]) <= tolerance;
      }
    }
    wrong += same ? 0 : 1;
  }
  return wrong;
}

TEST(DracoCodecTest, FaceIdsMapEdgebreakerQuantisedFacesBackToTheClientsOrder) {
  const TriangleMesh fandisk = Fandisk();
  DracoEncodeOptions options;
  options.method = DracoMethod::kEdgebreaker;
  options.position_quantization_bits = 14;
  options.write_face_ids = true;
  absl::StatusOr<std::string> bytes = EncodeMeshToDraco(fandisk, options);
  ASSERT_TRUE(bytes.ok()) << bytes.status();
  absl::StatusOr<std::string> sequential = EncodeMeshToDraco(fandisk);
  ASSERT_TRUE(sequential.ok());
  std::cout << "fandisk: sequential lossless " << sequential->size()
            << " bytes, edgebreaker 14-bit with face ids " << bytes->size() << " bytes\n";
  EXPECT_LT(bytes->size() * 2, sequential->size());

  absl::StatusOr<DecodedDracoMesh> decoded = DecodeDracoMeshWithFaceIds(*bytes);
  ASSERT_TRUE(decoded.ok()) << decoded.status();
  EXPECT_TRUE(decoded->has_face_ids);
  EXPECT_EQ(decoded->mesh.num_vertices(), fandisk.num_vertices());
  EXPECT_TRUE(ValidateMesh(decoded->mesh).ok());
  // The bytes held the faces in edgebreaker's order, which is not the client's.
  ASSERT_EQ(decoded->original_face.size(), fandisk.num_faces());
  size_t in_place = 0;
  for (size_t d = 0; d < decoded->original_face.size(); ++d) {
    in_place += decoded->original_face[d] == d ? 1 : 0;
  }
  EXPECT_LT(in_place, fandisk.num_faces() / 10);
  // Each face is back at its own index, within the quantisation step.
  float extent = 0;
  for (float x : fandisk.positions) extent = std::max(extent, std::abs(x));
  const float step = 2 * extent / (1 << 14);
  EXPECT_EQ(FacesOutOfPlace(fandisk, decoded->mesh, step), 0u);

  // DecodeDracoMesh gives the same mesh.
  absl::StatusOr<TriangleMesh> plain = DecodeDracoMesh(*bytes);
  ASSERT_TRUE(plain.ok());
  EXPECT_EQ(plain->indices, decoded->mesh.indices);

  // Without the ids the same method leaves the faces in edgebreaker's order.
  options.write_face_ids = false;
  absl::StatusOr<DecodedDracoMesh> unordered =
      DecodeDracoMeshWithFaceIds(*EncodeMeshToDraco(fandisk, options));
  ASSERT_TRUE(unordered.ok());
  EXPECT_FALSE(unordered->has_face_ids);
  EXPECT_TRUE(unordered->original_face.empty());
  EXPECT_GT(FacesOutOfPlace(fandisk, unordered->mesh, step), fandisk.num_faces() * 9 / 10);
}

TEST(DracoCodecTest, FaceIdsLosslessEdgebreakerIsExact) {
  const TriangleMesh grid = Grid(6);
  DracoEncodeOptions options;
  options.method = DracoMethod::kEdgebreaker;
  options.write_face_ids = true;
  absl::StatusOr<TriangleMesh> decoded = RoundTrip(grid, options);
  ASSERT_TRUE(decoded.ok()) << decoded.status();
  EXPECT_EQ(FacesOutOfPlace(grid, *decoded, 0.0f), 0u);
}

std::vector<uint32_t> Iota(size_t n) {
  std::vector<uint32_t> ids(n);
  std::iota(ids.begin(), ids.end(), 0u);
  return ids;
}

TEST(DracoCodecTest, FaceIdsFromTheForeignEncoderRecipeMapBackExactly) {
  const TriangleMesh fandisk = Fandisk();
  absl::StatusOr<DecodedDracoMesh> decoded =
      DecodeDracoMeshWithFaceIds(EncodeLikeForeignEncoder(fandisk, Iota(fandisk.num_faces())));
  ASSERT_TRUE(decoded.ok()) << decoded.status();
  EXPECT_TRUE(decoded->has_face_ids);
  // Fandisk has no two vertices at one position, so welding by position restores them.
  EXPECT_EQ(decoded->mesh.num_vertices(), fandisk.num_vertices());
  EXPECT_TRUE(ValidateMesh(decoded->mesh).ok());
  float extent = 0;
  for (float x : fandisk.positions) extent = std::max(extent, std::abs(x));
  EXPECT_EQ(FacesOutOfPlace(fandisk, decoded->mesh, 2 * extent / (1 << 11)), 0u);
}

TEST(DracoCodecTest, FaceIdsThatAreNotAPermutationAreRefused) {
  const TriangleMesh grid = Grid(4);
  std::vector<uint32_t> ids = Iota(grid.num_faces());
  ids[7] = 3;  // Face 3's id twice, id 7 nowhere.
  absl::StatusOr<TriangleMesh> decoded = DecodeDracoMesh(EncodeLikeForeignEncoder(grid, ids));
  EXPECT_EQ(decoded.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(Message(decoded.status()), HasSubstr("mlclust_face_id 3 is on more than one face"));

  ids = Iota(grid.num_faces());
  ids[5] = 40;  // As if the encoder had dropped a face.
  decoded = DecodeDracoMesh(EncodeLikeForeignEncoder(grid, ids));
  EXPECT_EQ(decoded.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(Message(decoded.status()), HasSubstr("mlclust_face_id 40, but the mesh has 32"));

  decoded = DecodeDracoMesh(EncodeLikeForeignEncoder(
      grid, Iota(grid.num_faces()), draco::MESH_EDGEBREAKER_ENCODING, draco::DT_UINT32, true));
  EXPECT_EQ(decoded.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(Message(decoded.status()), HasSubstr("values on its corners"));

  decoded = DecodeDracoMesh(EncodeLikeForeignEncoder(
      grid, Iota(grid.num_faces()), draco::MESH_EDGEBREAKER_ENCODING, draco::DT_FLOAT32));
  EXPECT_EQ(decoded.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(Message(decoded.status()), HasSubstr("must have 1 integer component"));

  decoded = DecodeDracoMesh(
      EncodeLikeForeignEncoder(grid, Iota(grid.num_faces()), draco::MESH_SEQUENTIAL_ENCODING));
  EXPECT_EQ(decoded.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(Message(decoded.status()), HasSubstr("needs an edgebreaker payload"));

  // Our encoder refuses ids with the sequential method.
  DracoEncodeOptions sequential_ids;
  sequential_ids.write_face_ids = true;
  EXPECT_EQ(EncodeMeshToDraco(grid, sequential_ids).status().code(),
            absl::StatusCode::kInvalidArgument);
}

// ---------------------------------------------------------------------------------------
// Untrusted bytes.

TEST(DracoCodecTest, RefusesEmptyAndNonDracoBytes) {
  EXPECT_THAT(Message(DecodeDracoMesh("").status()), HasSubstr("empty"));
  for (const std::string& bytes : {std::string("DRACO"), std::string("DRAC"),
                                   std::string("OFF\n3 1 0\n"), std::string(1000, '\0')}) {
    EXPECT_EQ(DecodeDracoMesh(bytes).status().code(), absl::StatusCode::kInvalidArgument) << bytes;
  }
}

TEST(DracoCodecTest, RefusesPointClouds) {
  draco::PointCloud cloud;
  cloud.set_num_points(3);
  draco::GeometryAttribute position;
  position.Init(draco::GeometryAttribute::POSITION, nullptr, 3, draco::DT_FLOAT32, false,
                sizeof(float) * 3, 0);
  const int id = cloud.AddAttribute(position, true, 3);
  const float xyz[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  for (uint32_t p = 0; p < 3; ++p) {
    cloud.attribute(id)->SetAttributeValue(draco::AttributeValueIndex(p), &xyz[3 * p]);
  }
  draco::ExpertEncoder encoder(cloud);
  draco::EncoderBuffer buffer;
  ASSERT_TRUE(encoder.EncodeToBuffer(&buffer).ok());
  absl::StatusOr<TriangleMesh> decoded = DecodeDracoMesh(std::string(buffer.data(), buffer.size()));
  EXPECT_EQ(decoded.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(Message(decoded.status()), HasSubstr("point cloud"));
}

// Found by fuzz_draco (fuzz/corpus/draco/bool_positions.drc): a POSITION attribute of
// Draco's bool type made the decoder read payload bytes as bools (undefined behaviour).
TEST(DracoCodecTest, RefusesPositionsThatAreNotNumbers) {
  draco::Mesh mesh;
  mesh.set_num_points(3);
  draco::GeometryAttribute position;
  position.Init(draco::GeometryAttribute::POSITION, nullptr, 3, draco::DT_BOOL, false, 3, 0);
  const int id = mesh.AddAttribute(position, true, 3);
  const uint8_t xyz[9] = {0, 0, 0, 128, 0, 0, 0, 1, 0};
  for (uint32_t p = 0; p < 3; ++p) {
    mesh.attribute(id)->SetAttributeValue(draco::AttributeValueIndex(p), &xyz[3 * p]);
  }
  mesh.AddFace({draco::PointIndex(0), draco::PointIndex(1), draco::PointIndex(2)});
  draco::ExpertEncoder encoder(mesh);
  encoder.SetEncodingMethod(draco::MESH_SEQUENTIAL_ENCODING);
  draco::EncoderBuffer buffer;
  ASSERT_TRUE(encoder.EncodeToBuffer(&buffer).ok());
  absl::StatusOr<TriangleMesh> decoded = DecodeDracoMesh(std::string(buffer.data(), buffer.size()));
  EXPECT_EQ(decoded.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(Message(decoded.status()), HasSubstr("POSITION attribute has data type 11"));
  // The fuzzer's input: the same, reached by mutating a sequential payload.
  const std::string fuzzer_input = ReadFuzzSeed("draco/bool_positions.drc");
  ASSERT_FALSE(fuzzer_input.empty());
  decoded = DecodeDracoMesh(fuzzer_input);
  EXPECT_EQ(decoded.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(Message(decoded.status()), HasSubstr("POSITION attribute has data type"));
}

// Every decode below must return (ok or not) without crashing; run this binary under
// ASan or valgrind to catch the quiet memory errors too.
TEST(DracoCodecTest, SurvivesRandomBytes) {
  std::mt19937 random(1);
  const std::string valid = *EncodeMeshToDraco(Grid(5));
  for (int i = 0; i < 3000; ++i) {
    std::string bytes(std::uniform_int_distribution<size_t>(0, 300)(random), '\0');
    for (char& c : bytes) c = static_cast<char>(random());
    // Half of them get a valid header, so that they reach the decoders proper.
    if (i % 2 == 1) bytes = valid.substr(0, 11) + bytes;
    absl::StatusOr<TriangleMesh> decoded = DecodeDracoMesh(bytes);
    if (!decoded.ok()) {
      EXPECT_EQ(decoded.status().code(), absl::StatusCode::kInvalidArgument);
    }
  }
}

TEST(DracoCodecTest, RefusesEveryTruncation) {
  DracoEncodeOptions q10, raw_indices;
  q10.position_quantization_bits = 10;
  raw_indices.speed = 10;
  const TriangleMesh fandisk = Fandisk();
  for (const std::string& valid :
       {*EncodeMeshToDraco(Tetrahedron()), *EncodeMeshToDraco(Grid(8)),
        *EncodeMeshToDraco(Grid(8), raw_indices), *EncodeMeshToDraco(Grid(8), q10),
        *EncodeMeshToDraco(fandisk), *EncodeMeshToDraco(fandisk, q10),
        EncodeWithDraco(fandisk, draco::MESH_EDGEBREAKER_ENCODING, 10)}) {
    const size_t stride = std::max<size_t>(1, valid.size() / 400);
    for (size_t length = 0; length < valid.size(); length += stride) {
      absl::StatusOr<TriangleMesh> decoded = DecodeDracoMesh(valid.substr(0, length));
      EXPECT_EQ(decoded.status().code(), absl::StatusCode::kInvalidArgument)
          << length << " of " << valid.size() << " bytes";
    }
  }
}

TEST(DracoCodecTest, SurvivesCorruptedBytes) {
  DracoEncodeOptions q12, raw_indices, face_ids;
  q12.position_quantization_bits = 12;
  raw_indices.speed = 10;
  face_ids.method = DracoMethod::kEdgebreaker;
  face_ids.position_quantization_bits = 12;
  face_ids.write_face_ids = true;
  const TriangleMesh grid = Grid(12);
  std::mt19937 random(3);
  for (const std::string& valid : {*EncodeMeshToDraco(grid), *EncodeMeshToDraco(grid, q12),
                                   *EncodeMeshToDraco(grid, raw_indices),
                                   EncodeWithDraco(grid, draco::MESH_EDGEBREAKER_ENCODING, 12),
                                   *EncodeMeshToDraco(grid, face_ids)}) {
    for (int i = 0; i < 1500; ++i) {
      std::string bytes = valid;
      const int changes = 1 + i % 4;
      for (int k = 0; k < changes; ++k) {
        const size_t at = std::uniform_int_distribution<size_t>(0, bytes.size() - 1)(random);
        bytes[at] = static_cast<char>(random());
      }
      absl::StatusOr<TriangleMesh> decoded = DecodeDracoMesh(bytes);
      if (decoded.ok()) {
        // Whatever came back is an indexed mesh whose indices are in range.
        for (uint32_t index : decoded->indices) ASSERT_LT(index, decoded->num_vertices());
      } else {
        EXPECT_EQ(decoded.status().code(), absl::StatusCode::kInvalidArgument);
      }
    }
  }
}

// A Draco mesh header ("DRACO", version, mesh, method, no flags) followed by `body`.
std::string DracoHeader(uint8_t major, uint8_t minor, uint8_t method, const std::string& body) {
  std::string bytes = "DRACO";
  bytes += static_cast<char>(major);
  bytes += static_cast<char>(minor);
  bytes += static_cast<char>(draco::TRIANGULAR_MESH);
  bytes += static_cast<char>(method);
  bytes += std::string(2, '\0');  // flags: no metadata
  return bytes + body;
}

std::string Fixed32(uint32_t value) {
  std::string bytes(4, '\0');
  for (int i = 0; i < 4; ++i) bytes[i] = static_cast<char>((value >> (8 * i)) & 0xff);
  return bytes;
}

std::string Varint(uint32_t value) {
  std::string bytes;
  do {
    uint8_t byte = value & 0x7f;
    value >>= 7;
    if (value != 0) byte |= 0x80;
    bytes += static_cast<char>(byte);
  } while (value != 0);
  return bytes;
}

// fuzz/corpus/draco/edgebreaker_declares_354m_faces.drc: 110 bytes of bitstream 1.0 whose
// edgebreaker header declares 353,703,189 faces. Before the header check Draco sized its
// corner table from that count: 8.4 GB written and 14 s before "Failed to decode".
TEST(DracoCodecTest, RefusesTheFuzzersHugeDeclaredConnectivityWithoutAllocating) {
  const std::string bytes = ReadFuzzSeed("draco/edgebreaker_declares_354m_faces.drc");
  ASSERT_EQ(bytes.size(), 110u);
  ScopedAllocationBudget watch(size_t{1} << 40);
  const absl::StatusOr<DecodedDracoMesh> decoded = DecodeDracoMeshWithFaceIds(bytes);
  EXPECT_LT(watch.allocated_bytes(), size_t{1} << 20);
  ASSERT_EQ(decoded.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(Message(decoded.status()), HasSubstr("declares 353703189 faces"));
  EXPECT_THAT(Message(decoded.status()), HasSubstr("110-byte payload"));
}

// Every layout Draco 1.5.5 reads counts in: fixed 32-bit before bitstream 2.0, varints
// from 2.0, edgebreaker's num_new_vertices before 2.2, sequential fixed before 2.2.
TEST(DracoCodecTest, RefusesHugeDeclaredCountsInEveryBitstreamVersion) {
  const uint32_t huge = 300'000'000;
  const uint8_t eb = draco::MESH_EDGEBREAKER_ENCODING;
  const uint8_t seq = draco::MESH_SEQUENTIAL_ENCODING;
  const std::string tail(64, '\x15');
  struct Case {
    const char* name;
    std::string bytes;
  };
  const std::vector<Case> cases = {
      {"edgebreaker 1.0", DracoHeader(1, 0, eb,
                                      "\x02" + Fixed32(0) + Fixed32(3) + Fixed32(huge) + "\x00" +
                                          Fixed32(1) + Fixed32(0) + tail)},
      {"edgebreaker 2.0", DracoHeader(2, 0, eb,
                                      "\x02" + Varint(0) + Varint(3) + Varint(huge) +
                                          std::string(1, '\0') + Varint(1) + Varint(0) + tail)},
      {"edgebreaker 2.2", DracoHeader(2, 2, eb,
                                      std::string("\x00", 1) + Varint(3) + Varint(huge) +
                                          std::string(1, '\0') + Varint(1) + Varint(0) + tail)},
      {"sequential 2.1", DracoHeader(2, 1, seq, Fixed32(huge) + Fixed32(3) + tail)},
      {"sequential 2.2", DracoHeader(2, 2, seq, Varint(huge) + Varint(3) + tail)},
      {"sequential 2.2 points", DracoHeader(2, 2, seq, Varint(1) + Varint(huge) + tail)},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    EXPECT_EQ(CheckDracoDeclaredCounts(c.bytes).code(), absl::StatusCode::kInvalidArgument);
    ScopedAllocationBudget watch(size_t{1} << 40);
    const absl::StatusOr<DecodedDracoMesh> decoded = DecodeDracoMeshWithFaceIds(c.bytes);
    EXPECT_LT(watch.allocated_bytes(), size_t{1} << 20);
    ASSERT_EQ(decoded.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_THAT(Message(decoded.status()), HasSubstr("declares 300000000"));
  }
}

TEST(DracoCodecTest, RefusesVerticesAndAttributeConnectivitiesTheFacesCannotHave) {
  const uint8_t eb = draco::MESH_EDGEBREAKER_ENCODING;
  const std::string tail(64, '\x15');
  const std::string vertices =
      DracoHeader(2, 2, eb,
                  std::string("\x00", 1) + Varint(1000) + Varint(10) + std::string(1, '\0') +
                      Varint(10) + Varint(0) + tail);
  EXPECT_THAT(Message(CheckDracoDeclaredCounts(vertices)), HasSubstr("1000 vertices"));
  const std::string attributes =
      DracoHeader(2, 2, eb,
                  std::string("\x00", 1) + Varint(12) + Varint(10) + std::string(1, '\xff') +
                      Varint(10) + Varint(0) + tail);
  EXPECT_THAT(Message(CheckDracoDeclaredCounts(attributes)),
              HasSubstr("255 attributes with their own connectivity"));
}

TEST(DracoCodecTest, RealPayloadsPassTheLimitsWithEveryMethod) {
  const TriangleMesh fandisk = Fandisk();
  for (DracoMethod method : {DracoMethod::kSequential, DracoMethod::kEdgebreaker}) {
    for (int bits : {0, 8, 14}) {
      DracoEncodeOptions options;
      options.method = method;
      options.position_quantization_bits = bits;
      options.write_face_ids = method == DracoMethod::kEdgebreaker;
      const std::string bytes = *EncodeMeshToDraco(fandisk, options);
      EXPECT_TRUE(CheckDracoDeclaredCounts(bytes).ok());
      const absl::StatusOr<DecodedDracoMesh> decoded = DecodeDracoMeshWithFaceIds(bytes);
      ASSERT_TRUE(decoded.ok()) << decoded.status();
      EXPECT_EQ(decoded->mesh.num_faces(), fandisk.num_faces());
    }
  }
  // A regular grid at 8-bit positions is the most compressible real mesh we could make
  // (16 faces per byte at speed 0): under the 64-per-byte bound.
  DracoEncodeOptions dense;
  dense.method = DracoMethod::kEdgebreaker;
  dense.position_quantization_bits = 8;
  dense.speed = 0;
  const TriangleMesh grid = Grid(300);
  const std::string bytes = *EncodeMeshToDraco(grid, dense);
  EXPECT_GT(grid.num_faces(), 5 * bytes.size());
  const absl::StatusOr<DecodedDracoMesh> decoded = DecodeDracoMeshWithFaceIds(bytes);
  ASSERT_TRUE(decoded.ok()) << decoded.status();
  EXPECT_EQ(decoded->mesh.num_faces(), grid.num_faces());
}

TEST(DracoCodecTest, TheDecodeBudgetStopsWhatTheHeaderDoesNotSay) {
  const std::string bytes = *EncodeMeshToDraco(Fandisk());
  DracoDecodeLimits tight;
  tight.min_decode_budget_bytes = 64 * 1024;
  tight.decode_budget_per_byte = 0;
  const absl::StatusOr<DecodedDracoMesh> decoded = DecodeDracoMeshWithFaceIds(bytes, tight);
  ASSERT_EQ(decoded.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(Message(decoded.status()), HasSubstr("more memory than a"));
  // The same bytes within the default budget.
  EXPECT_TRUE(DecodeDracoMeshWithFaceIds(bytes).ok());
}

TEST(AllocationBudgetTest, RefusesPastTheBudgetOnlyInsideTheScope) {
  {
    ScopedAllocationBudget budget(1 << 20);
    std::vector<char> small(1000);
    EXPECT_GE(budget.allocated_bytes(), 1000u);
    EXPECT_THROW(std::vector<char>(2 << 20), std::bad_alloc);
    EXPECT_TRUE(budget.exceeded());
    EXPECT_EQ(new (std::nothrow) char[2 << 20], nullptr);
  }
  std::vector<char> big(2 << 20);  // no scope: no budget
  EXPECT_EQ(big.size(), size_t{2} << 20);
}

TEST(AllocationBudgetTest, InnerScopesCountAgainstTheOuterOnes) {
  ScopedAllocationBudget outer(1 << 20);
  {
    ScopedAllocationBudget inner(size_t{1} << 30);
    std::vector<char> within(600 << 10);
    EXPECT_GE(inner.allocated_bytes(), size_t{600} << 10);
    // The inner budget allows it; the outer one, with 600 KiB spent, does not.
    EXPECT_THROW(std::vector<char>(600 << 10), std::bad_alloc);
    EXPECT_TRUE(outer.exceeded());
  }
  EXPECT_GE(outer.allocated_bytes(), size_t{600} << 10);
}

}  // namespace
}  // namespace mlclust
