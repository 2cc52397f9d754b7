#include "core/io/mesh_io.h"

#include <assimp/scene.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <assimp/Importer.hpp>
#include <bit>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <numeric>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "absl/strings/escaping.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "core/io/draco_codec.h"
#include "core/mesh/mesh.h"
#include "nlohmann/json.hpp"
#include "tests/fixtures/files.h"
#include "tests/fixtures/test_meshes.h"

namespace mlclust {
namespace {

using testing::DataPath;
using testing::Grid;
using ::testing::HasSubstr;
using testing::MakeMesh;
using testing::ReadFileBytes;
using testing::ReadFuzzSeed;
using testing::Tetrahedron;

// ---------------------------------------------------------------------------------------
// Helpers.

using MeshIoTest = testing::TempDirectoryTest;

std::array<float, 3> CornerPosition(const TriangleMesh& mesh, size_t face, int corner) {
  const float* p = &mesh.positions[3 * size_t{mesh.indices[3 * face + corner]}];
  return {p[0], p[1], p[2]};
}

// Face i of `actual` has the same three positions, in the same corner order, as face i of
// `expected`, bit for bit.
void ExpectSameFacePositions(const TriangleMesh& expected, const TriangleMesh& actual) {
  ASSERT_EQ(actual.num_faces(), expected.num_faces());
  for (size_t f = 0; f < expected.num_faces(); ++f) {
    for (int c = 0; c < 3; ++c) {
      const auto want = CornerPosition(expected, f, c);
      const auto got = CornerPosition(actual, f, c);
      ASSERT_EQ(std::memcmp(want.data(), got.data(), sizeof(want)), 0)
          << "face " << f << " corner " << c << ": want (" << want[0] << ", " << want[1] << ", "
          << want[2] << ") got (" << got[0] << ", " << got[1] << ", " << got[2] << ")";
    }
  }
}

// Twice the signed area of face f projected on z = 0 (positive: counter-clockwise seen
// from +z).
double SignedAreaXy(const TriangleMesh& mesh, size_t f) {
  const auto a = CornerPosition(mesh, f, 0), b = CornerPosition(mesh, f, 1),
             c = CornerPosition(mesh, f, 2);
  return (double{b[0]} - a[0]) * (double{c[1]} - a[1]) -
         (double{b[1]} - a[1]) * (double{c[0]} - a[0]);
}

// A 4 x 4 grid (32 faces, 25 vertices) with its faces shuffled and each face's corners
// rotated, so that neither face order nor corner order is the natural one. Coordinates
// are exact in decimal (multiples of 1/8), so text formats reproduce them bit for bit.
TriangleMesh ShuffledGrid() {
  TriangleMesh grid = Grid(4);
  for (size_t i = 0; i < grid.positions.size(); ++i) {
    grid.positions[i] = grid.positions[i] * 0.5f + 0.125f * static_cast<float>(i % 3);
  }
  std::mt19937 random(7);
  std::vector<size_t> order(grid.num_faces());
  std::iota(order.begin(), order.end(), 0);
  for (size_t i = order.size() - 1; i > 0; --i) {
    std::swap(order[i], order[std::uniform_int_distribution<size_t>(0, i)(random)]);
  }
  TriangleMesh shuffled{grid.positions, {}};
  for (size_t k = 0; k < order.size(); ++k) {
    const int rotation = static_cast<int>(k % 3);
    for (int c = 0; c < 3; ++c) {
      shuffled.indices.push_back(grid.indices[3 * order[k] + (c + rotation) % 3]);
    }
  }
  return shuffled;
}

// The vertex lines ("PREFIX x y z") and the triangle lines ("PREFIX a b c", indices from
// `first_index`) of the text formats below.
void AppendVerticesAndTriangles(const TriangleMesh& mesh, const char* vertex_prefix,
                                const char* face_prefix, uint32_t first_index, std::string& out) {
  for (size_t v = 0; v < mesh.num_vertices(); ++v) {
    absl::StrAppendFormat(&out, "%s%.9g %.9g %.9g\n", vertex_prefix, mesh.positions[3 * v],
                          mesh.positions[3 * v + 1], mesh.positions[3 * v + 2]);
  }
  for (size_t f = 0; f < mesh.num_faces(); ++f) {
    absl::StrAppend(&out, face_prefix, mesh.indices[3 * f] + first_index, " ",
                    mesh.indices[3 * f + 1] + first_index, " ",
                    mesh.indices[3 * f + 2] + first_index, "\n");
  }
}

std::string ToOff(const TriangleMesh& mesh) {
  std::string out = absl::StrCat("OFF\n", mesh.num_vertices(), " ", mesh.num_faces(), " 0\n");
  AppendVerticesAndTriangles(mesh, "", "3 ", 0, out);
  return out;
}

std::string ToObj(const TriangleMesh& mesh) {
  std::string out = "# written by mesh_io_test\n";
  AppendVerticesAndTriangles(mesh, "v ", "f ", 1, out);  // OBJ indices are 1-based.
  return out;
}

std::string ToPlyAscii(const TriangleMesh& mesh) {
  std::string out =
      absl::StrCat("ply\nformat ascii 1.0\nelement vertex ", mesh.num_vertices(),
                   "\nproperty float x\nproperty float y\nproperty float z\nelement face ",
                   mesh.num_faces(), "\nproperty list uchar int vertex_indices\nend_header\n");
  AppendVerticesAndTriangles(mesh, "", "3 ", 0, out);
  return out;
}

template <typename T>
void AppendRaw(std::string& out, T value) {  // The tests run on little-endian hosts.
  static_assert(std::endian::native == std::endian::little);
  out.append(reinterpret_cast<const char*>(&value), sizeof(value));
}

std::string ToPlyBinary(const TriangleMesh& mesh) {
  std::string out =
      absl::StrCat("ply\nformat binary_little_endian 1.0\nelement vertex ", mesh.num_vertices(),
                   "\nproperty float x\nproperty float y\nproperty float z\nelement face ",
                   mesh.num_faces(), "\nproperty list uchar int vertex_indices\nend_header\n");
  for (float x : mesh.positions) AppendRaw(out, x);
  for (size_t f = 0; f < mesh.num_faces(); ++f) {
    AppendRaw<uint8_t>(out, 3);
    for (int c = 0; c < 3; ++c) AppendRaw<int32_t>(out, mesh.indices[3 * f + c]);
  }
  return out;
}

std::string ToStlAscii(const TriangleMesh& mesh) {
  std::string out = "solid test\n";
  for (size_t f = 0; f < mesh.num_faces(); ++f) {
    out += "facet normal 0 0 1\n outer loop\n";
    for (int c = 0; c < 3; ++c) {
      const auto p = CornerPosition(mesh, f, c);
      absl::StrAppendFormat(&out, "  vertex %.9g %.9g %.9g\n", p[0], p[1], p[2]);
    }
    out += " endloop\nendfacet\n";
  }
  return out + "endsolid test\n";
}

std::string ToStlBinary(const TriangleMesh& mesh) {
  std::string out(80, ' ');  // Must not start with "solid", or readers take it for ASCII.
  out.replace(0, 6, "binary");
  AppendRaw<uint32_t>(out, static_cast<uint32_t>(mesh.num_faces()));
  for (size_t f = 0; f < mesh.num_faces(); ++f) {
    for (int i = 0; i < 3; ++i) AppendRaw<float>(out, i == 2 ? 1.0f : 0.0f);
    for (int c = 0; c < 3; ++c) {
      for (float x : CornerPosition(mesh, f, c)) AppendRaw(out, x);
    }
    AppendRaw<uint16_t>(out, 0);
  }
  return out;
}

// ---------------------------------------------------------------------------------------
// OFF.

// A tiny OFF reader independent of the one under test: whitespace tokens, strtof.
TriangleMesh ReadTriangleOffIndependently(const std::string& path) {
  std::istringstream in(ReadFileBytes(path));
  std::string keyword;
  size_t num_vertices = 0, num_faces = 0, num_edges = 0;
  in >> keyword >> num_vertices >> num_faces >> num_edges;
  TriangleMesh mesh;
  std::string token;
  for (size_t i = 0; i < 3 * num_vertices && in >> token; ++i) {
    mesh.positions.push_back(std::strtof(token.c_str(), nullptr));
  }
  for (size_t f = 0; f < num_faces; ++f) {
    int corners = 0;
    in >> corners;
    EXPECT_EQ(corners, 3) << "face " << f;
    for (int c = 0; c < 3; ++c) {
      uint32_t index = 0;
      in >> index;
      mesh.indices.push_back(index);
    }
  }
  return mesh;
}

TEST_F(MeshIoTest, FandiskMatchesAnIndependentReadingFaceByFace) {
  const std::string path = DataPath("fandisk.off");
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(path);
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  EXPECT_EQ(mesh->num_vertices(), 6475u);
  EXPECT_EQ(mesh->num_faces(), 12946u);
  EXPECT_TRUE(ValidateMesh(*mesh).ok()) << ValidateMesh(*mesh);

  const TriangleMesh reference = ReadTriangleOffIndependently(path);
  ASSERT_EQ(reference.num_vertices(), 6475u);
  ASSERT_EQ(reference.num_faces(), 12946u);
  ExpectSameFacePositions(reference, *mesh);
  // OFF indexes its vertices, so they are kept as written: same ids, same bits.
  EXPECT_EQ(mesh->indices, reference.indices);
  ASSERT_EQ(mesh->positions.size(), reference.positions.size());
  EXPECT_EQ(std::memcmp(mesh->positions.data(), reference.positions.data(),
                        reference.positions.size() * sizeof(float)),
            0);
}

TEST_F(MeshIoTest, OffVerticesAtOnePositionStayDistinct) {
  // elephant-with-holes.off lists 65 vertices twice at one position around its holes;
  // welding them would pinch the surface into non-manifold vertices.
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(DataPath("elephant-with-holes.off"));
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  EXPECT_EQ(mesh->num_vertices(), 2798u);
  EXPECT_EQ(mesh->num_faces(), 4463u);
  EXPECT_TRUE(ValidateMesh(*mesh).ok()) << ValidateMesh(*mesh);
}

TEST_F(MeshIoTest, OffPolygonsBecomeTrianglesInPlace) {
  // A triangle, a convex quad, a concave quad (reflex corner at vertex 7), a pentagon,
  // a line and a point (dropped), then a triangle again.
  const std::string path = Write("polygons.off",
                                 "OFF\n"
                                 "13 7 0\n"
                                 "0 0 0\n1 0 0\n1 1 0\n0 1 0\n"             // 0-3: unit square
                                 "4 0 0\n8 0 0\n8 4 0\n7 1 0\n"             // 4-7: dart
                                 "10 0 0\n12 0 0\n13 1 0\n11 2 0\n9 1 0\n"  // 8-12: pentagon
                                 "3 0 1 2\n"
                                 "4 0 1 2 3\n"
                                 "4 4 5 6 7\n"
                                 "5 8 9 10 11 12\n"
                                 "2 0 1\n"
                                 "1 0\n"
                                 "3 2 3 0\n");
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(path);
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  // 1 + 2 + 2 + 3 + 1 triangles; the dart is cut along 5-7, the only diagonal inside it.
  EXPECT_EQ(mesh->indices, (std::vector<uint32_t>{0, 1, 2,                         // triangle
                                                  0, 1, 2,  0, 2,  3,              // convex quad
                                                  5, 6, 7,  4, 5,  7,              // dart
                                                  8, 9, 10, 8, 10, 11, 8, 11, 12,  // fan
                                                  2, 3, 0}));
  EXPECT_EQ(mesh->num_vertices(), 13u);
  for (size_t f = 0; f < mesh->num_faces(); ++f) {
    EXPECT_GT(SignedAreaXy(*mesh, f), 0) << "face " << f << " lost its winding";
  }
}

TEST_F(MeshIoTest, OffHeaderVariantsCommentsAndColours) {
  // Keyword and counts on one line, comments, CRLF, blank lines, vertex colours (COFF)
  // and face colours after the indices.
  const std::string path = Write("variants.off",
                                 "# a comment before the keyword\r\n"
                                 "COFF 4 2 5 # counts on the keyword's line\r\n"
                                 "\r\n"
                                 "0 0 0 255 0 0 255\r\n"
                                 "1.5e0 0 0 0 255 0 255  # exponent\r\n"
                                 "\t0 +1 0 0 0 255 255\r\n"
                                 "-0.25 -0.5 2 10 10 10 255\r\n"
                                 "3 0 1 2 0.5 0.5 0.5\r\n"
                                 "# between faces\r\n"
                                 "3 1 3 2\r\n");
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(path);
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  EXPECT_EQ(mesh->positions, (std::vector<float>{0, 0, 0, 1.5f, 0, 0, 0, 1, 0, -0.25f, -0.5f, 2}));
  EXPECT_EQ(mesh->indices, (std::vector<uint32_t>{0, 1, 2, 1, 3, 2}));
}

TEST_F(MeshIoTest, OffHomogeneousCoordinatesAreDivided) {
  const std::string path = Write("h.off", "4OFF\n3 1 0\n2 0 0 2\n4 0 0 2\n0 8 0 4\n3 0 1 2\n");
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(path);
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  EXPECT_EQ(mesh->positions, (std::vector<float>{1, 0, 0, 2, 0, 0, 0, 2, 0}));
}

TEST_F(MeshIoTest, OffKeywordIsRecognisedUnderAnyExtension) {
  // Assimp would otherwise take it, and its OFF reader drops faces of 10 corners.
  const std::string path = Write("decagon.txt",
                                 "OFF\n10 1 0\n"
                                 "2 0 0\n1.6 1.2 0\n0.6 1.9 0\n-0.6 1.9 0\n-1.6 1.2 0\n"
                                 "-2 0 0\n-1.6 -1.2 0\n-0.6 -1.9 0\n0.6 -1.9 0\n1.6 -1.2 0\n"
                                 "10 0 1 2 3 4 5 6 7 8 9\n");
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(path);
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  EXPECT_EQ(mesh->num_faces(), 8u);
  EXPECT_EQ(mesh->num_vertices(), 10u);
}

struct BadOff {
  const char* name;
  const char* text;
  const char* message;
};

TEST_F(MeshIoTest, OffRejectsWhatItCannotPlace) {
  const BadOff cases[] = {
      {"index_out_of_range", "OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 7\n",
       "line 7: face 1 corner 2 refers to vertex 7, but the file has 3 vertices"},
      {"missing_index", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1\n",
       "face 0 has 2 of its 3 vertex indices"},
      {"negative_index", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n",
       "'-1' is not a vertex index"},
      {"too_few_faces", "OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
       "the file ends after 1 of 2 faces"},
      {"too_few_vertices", "OFF\n4 1 0\n0 0 0\n1 0 0\n", "the file ends after 2 of 4 vertices"},
      {"two_vertices_per_line", "OFF\n3 1 0\n0 0 0 1 0 0\n0 1 0\n3 0 1 2\n",
       // Line-based, as CGAL reads it: "3 0 1 2" is taken for vertex 2.
       "line 5: the file ends after 0 of 1 faces"},
      {"short_vertex", "OFF\n3 1 0\n0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
       "vertex 0 has 2 coordinates, 3 are needed"},
      {"bad_coordinate", "OFF\n3 1 0\n0 0 zero\n1 0 0\n0 1 0\n3 0 1 2\n",
       "vertex 0: 'zero' is not a float coordinate"},
      {"float_overflow", "OFF\n3 1 0\n0 0 1e39\n1 0 0\n0 1 0\n3 0 1 2\n",
       "'1e39' is not a float coordinate"},
      {"bad_count", "OFF\nthree 1 0\n", "expected a count, found 'three'"},
      {"not_off", "COFFEE 3 1 0\n", "expected the OFF keyword or the vertex count"},
      {"binary", "OFF BINARY\n", "binary OFF is not supported"},
      {"dimension", "nOFF\n4\n3 1 0\n", "only 3-dimensional OFF is supported"},
      {"header_only", "OFF\n", "the file ends inside the header"},
      {"empty", "", "empty OFF file"},
      {"huge_counts", "OFF\n99999999999 1 0\n", "too many elements"},
      {"no_triangles", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n2 0 1\n", "holds no triangles"},
  };
  for (const BadOff& bad : cases) {
    const std::string path = Write(absl::StrCat(bad.name, ".off"), bad.text);
    absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(path);
    EXPECT_EQ(mesh.status().code(), absl::StatusCode::kInvalidArgument) << bad.name;
    EXPECT_THAT(std::string(mesh.status().message()), HasSubstr(bad.message)) << bad.name;
    EXPECT_THAT(std::string(mesh.status().message()), HasSubstr(path)) << bad.name;
  }
}

// ---------------------------------------------------------------------------------------
// Face order and positions through every format.

TEST_F(MeshIoTest, EveryFormatKeepsFaceOrderCornerOrderAndPositions) {
  const TriangleMesh source = ShuffledGrid();
  ASSERT_TRUE(ValidateMesh(source).ok());
  struct Format {
    std::string file;
    std::string content;
    bool keeps_vertex_ids;  // Indexed formats keep the file's vertices.
  };
  const Format formats[] = {
      {"grid.off", ToOff(source), true},       {"grid.obj", ToObj(source), false},
      {"grid.ply", ToPlyAscii(source), true},  {"grid_binary.ply", ToPlyBinary(source), true},
      {"grid.stl", ToStlAscii(source), false}, {"grid_binary.stl", ToStlBinary(source), false},
  };
  for (const Format& format : formats) {
    SCOPED_TRACE(format.file);
    absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(Write(format.file, format.content));
    ASSERT_TRUE(mesh.ok()) << mesh.status();
    ExpectSameFacePositions(source, *mesh);
    // Either way the 25 grid vertices come back once each: kept or welded.
    EXPECT_EQ(mesh->num_vertices(), 25u);
    EXPECT_TRUE(ValidateMesh(*mesh).ok()) << ValidateMesh(*mesh);
    if (format.keeps_vertex_ids) {
      EXPECT_EQ(mesh->indices, source.indices);
    }
  }
}

TEST_F(MeshIoTest, BinaryPlyPositionsArriveBitForBit) {
  // Values no decimal printing would keep: a subnormal, -0, and neighbours of 1.
  // Two faces share vertices, so the file's vertices are kept, the unused one too.
  TriangleMesh mesh = MakeMesh({std::nextafter(1.0f, 2.0f), 1e-40f, -0.0f,       //
                                std::nextafter(1.0f, 0.0f), 3.14159274f, 1e30f,  //
                                -7.0e-8f, 0.1f, 0.2f,                            //
                                42, 42, 42,                                      // unused
                                5, 6, 7},
                               {0, 1, 2, 2, 1, 4});
  absl::StatusOr<TriangleMesh> read = ReadMeshFile(Write("bits.ply", ToPlyBinary(mesh)));
  ASSERT_TRUE(read.ok()) << read.status();
  ASSERT_EQ(read->positions.size(), mesh.positions.size());
  EXPECT_EQ(std::memcmp(read->positions.data(), mesh.positions.data(),
                        mesh.positions.size() * sizeof(float)),
            0);
  EXPECT_EQ(read->indices, mesh.indices);
}

// ---------------------------------------------------------------------------------------
// OBJ, STL, glTF.

TEST_F(MeshIoTest, ObjQuadBecomesTwoTrianglesInOrder) {
  const std::string path = Write("quad.obj",
                                 "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\n"
                                 "f 1 2 5\n"
                                 "f 1 2 3 4\n"
                                 "l 1 5\n"
                                 "f 4 3 5\n");
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(path);
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  // Welded in first-seen order: 0 0 0, 1 0 0, 0 0 1, 1 1 0, 0 1 0.
  EXPECT_EQ(mesh->positions, (std::vector<float>{0, 0, 0, 1, 0, 0, 0, 0, 1, 1, 1, 0, 0, 1, 0}));
  EXPECT_EQ(mesh->indices, (std::vector<uint32_t>{0, 1, 2,           // f 1 2 5
                                                  0, 1, 3, 0, 3, 4,  // the quad, fanned
                                                  4, 3, 2}));        // f 4 3 5; l dropped
}

TEST_F(MeshIoTest, ObjConcaveQuadIsCutInside) {
  // Reflex corner at the 4th vertex: the fan from the 1st corner would cover area
  // outside the quad; the cut must run from the reflex corner.
  const std::string path = Write("dart.obj", "v 0 0 0\nv 4 0 0\nv 4 4 0\nv 3 1 0\nf 1 2 3 4\n");
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(path);
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  EXPECT_EQ(mesh->indices, (std::vector<uint32_t>{1, 2, 3, 0, 1, 3}));
  // Both counter-clockwise, and together exactly the quad's area (twice 4).
  EXPECT_DOUBLE_EQ(SignedAreaXy(*mesh, 0) + SignedAreaXy(*mesh, 1), 8.0);
  EXPECT_GT(SignedAreaXy(*mesh, 0), 0);
  EXPECT_GT(SignedAreaXy(*mesh, 1), 0);
}

TEST_F(MeshIoTest, ObjMaterialGroupsKeepFileOrder) {
  // Assimp makes a mesh per material run and per group; the faces must still come back
  // in file order. The .mtl file is missing, which is not an error.
  const std::string path = Write("groups.obj",
                                 "mtllib missing.mtl\n"
                                 "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\n"
                                 "usemtl A\nf 1 2 3\n"
                                 "usemtl B\nf 1 2 5\n"
                                 "usemtl A\nf 2 3 5\n"
                                 "g second\nf 3 4 5\n"
                                 "g first\nf 1 4 5\n");
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(path);
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  EXPECT_EQ(mesh->num_vertices(), 5u);
  EXPECT_EQ(mesh->indices, (std::vector<uint32_t>{0, 1, 2, 0, 1, 3, 1, 2, 3, 2, 4, 3, 0, 4, 3}));
}

TEST_F(MeshIoTest, StlCornersAreWeldedIntoSharedVertices) {
  const std::string path = Write("square.stl",
                                 "solid square\n"
                                 "facet normal 0 0 1\n outer loop\n"
                                 "  vertex 0 0 0\n  vertex 1 0 0\n  vertex 0 1 0\n"
                                 " endloop\nendfacet\n"
                                 "facet normal 0 0 1\n outer loop\n"
                                 "  vertex 1 0 0\n  vertex 1 1 0\n  vertex 0 1 0\n"
                                 " endloop\nendfacet\n"
                                 "endsolid square\n");
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(path);
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  EXPECT_EQ(mesh->positions, (std::vector<float>{0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0}));
  EXPECT_EQ(mesh->indices, (std::vector<uint32_t>{0, 1, 2, 1, 3, 2}));
  absl::StatusOr<FaceAdjacency> adjacency = BuildFaceAdjacency(*mesh);
  ASSERT_TRUE(adjacency.ok()) << adjacency.status();
  EXPECT_EQ(adjacency->neighbours[0][1], FaceId(1));  // Across the shared edge (1, 2).
}

TEST_F(MeshIoTest, StlNegativeZeroWeldsWithZero) {
  const std::string path = Write("zeros.stl",
                                 "solid z\nfacet normal 0 0 1\n outer loop\n"
                                 "  vertex 0 0 0\n  vertex 1 0 0\n  vertex 0 1 0\n"
                                 " endloop\nendfacet\nfacet normal 0 0 1\n outer loop\n"
                                 "  vertex -0 -0 -0\n  vertex 0 1 0\n  vertex -1 0 0\n"
                                 " endloop\nendfacet\nendsolid z\n");
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(path);
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  EXPECT_EQ(mesh->num_vertices(), 4u);
  EXPECT_EQ(mesh->indices, (std::vector<uint32_t>{0, 1, 2, 0, 2, 3}));
}

// A unit quad (two triangles: 0 1 2, 0 2 3) used by three nodes: as it is, moved by
// +10 in x, and mirrored in x. The buffer holds six uint16 indices, then four float
// positions: (0 0 0) (1 0 0) (1 1 0) (0 1 0).
constexpr char kQuadGltf[] = R"({
  "asset": {"version": "2.0"},
  "scene": 0,
  "scenes": [{"nodes": [0, 1, 2]}],
  "nodes": [
    {"name": "plain", "mesh": 0},
    {"name": "moved", "mesh": 0, "translation": [10, 0, 0]},
    {"name": "mirrored", "mesh": 0, "scale": [-1, 1, 1]}
  ],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 1}, "indices": 0}]}],
  "buffers": [{"byteLength": 60, "uri": "data:application/octet-stream;base64,AAABAAIAAAACAAMAAAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAACAPwAAgD8AAAAAAAAAAAAAgD8AAAAA"}],
  "bufferViews": [
    {"buffer": 0, "byteOffset": 0, "byteLength": 12, "target": 34963},
    {"buffer": 0, "byteOffset": 12, "byteLength": 48, "target": 34962}
  ],
  "accessors": [
    {"bufferView": 0, "componentType": 5123, "count": 6, "type": "SCALAR"},
    {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3",
     "min": [0, 0, 0], "max": [1, 1, 0]}
  ]
})";

TEST_F(MeshIoTest, GltfNodesPlaceInstanceAndMirrorTheMesh) {
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(Write("quad.gltf", kQuadGltf));
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  ASSERT_EQ(mesh->num_faces(), 6u);
  // The quad indexes shared vertices, so each instance keeps its own four.
  EXPECT_EQ(mesh->num_vertices(), 12u);
  const std::array<float, 3> expected_first_corner[6] = {{0, 0, 0},  {0, 0, 0}, {10, 0, 0},
                                                         {10, 0, 0}, {0, 0, 0}, {0, 0, 0}};
  for (size_t f = 0; f < 6; ++f) {
    EXPECT_EQ(CornerPosition(*mesh, f, 0), expected_first_corner[f]) << "face " << f;
    // The mirrored copy has its corners swapped back to counter-clockwise.
    EXPECT_DOUBLE_EQ(SignedAreaXy(*mesh, f), 1.0) << "face " << f;
  }
  EXPECT_EQ(CornerPosition(*mesh, 2, 1), (std::array<float, 3>{11, 0, 0}));
  EXPECT_EQ(CornerPosition(*mesh, 4, 2), (std::array<float, 3>{-1, 0, 0}));
  EXPECT_EQ(CornerPosition(*mesh, 4, 1), (std::array<float, 3>{-1, 1, 0}));
}

// ---------------------------------------------------------------------------------------
// Draco files and errors.

TEST_F(MeshIoTest, DracoFilesAreDecodedWhateverTheExtensionCase) {
  const TriangleMesh tetrahedron = Tetrahedron();
  absl::StatusOr<std::string> bytes = EncodeMeshToDraco(tetrahedron);
  ASSERT_TRUE(bytes.ok()) << bytes.status();
  for (const char* name : {"tet.drc", "tet.DRC", "tet.bin"}) {  // .bin: by magic.
    absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(Write(name, *bytes));
    ASSERT_TRUE(mesh.ok()) << name << ": " << mesh.status();
    EXPECT_EQ(mesh->positions, tetrahedron.positions) << name;
    EXPECT_EQ(mesh->indices, tetrahedron.indices) << name;
  }
  absl::StatusOr<TriangleMesh> bad = ReadMeshFile(Write("bad.drc", "not draco at all"));
  EXPECT_EQ(bad.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(bad.status().message()), HasSubstr("bad.drc"));
}

TEST_F(MeshIoTest, MissingFileIsNotFound) {
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(Path("nothing-here.obj"));
  EXPECT_EQ(mesh.status().code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(std::string(mesh.status().message()), HasSubstr("nothing-here.obj"));
}

TEST_F(MeshIoTest, DirectoryIsInvalidArgument) {
  std::filesystem::create_directories(directory_ / "folder.obj");
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(Path("folder.obj"));
  EXPECT_EQ(mesh.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(mesh.status().message()), HasSubstr("not a regular file"));
}

TEST_F(MeshIoTest, UnreadableContentNamesFileAndImporterMessage) {
  const std::string path = Write("noise.xyz123", "\x01\x02 this is no mesh format \xff\n");
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(path);
  EXPECT_EQ(mesh.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(mesh.status().message()), HasSubstr(path));
  EXPECT_THAT(std::string(mesh.status().message()), HasSubstr("cannot be read: "));
  EXPECT_GT(mesh.status().message().size(), path.size() + 20) << "no importer message";
}

TEST_F(MeshIoTest, FilesWithoutTrianglesAreRefused) {
  for (const auto& [name, content] : std::vector<std::pair<std::string, std::string>>{
           {"lines.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2\nl 2 3\np 1\n"},
           {"points.ply",
            "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
            "property float z\nend_header\n0 0 0\n1 1 1\n"},
       }) {
    absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(Write(name, content));
    EXPECT_EQ(mesh.status().code(), absl::StatusCode::kInvalidArgument) << name;
    EXPECT_THAT(std::string(mesh.status().message()), HasSubstr(name));
  }
}

TEST_F(MeshIoTest, PlyIndexOutOfRangeIsRefused) {
  const std::string path = Write("oor.ply",
                                 "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                                 "property float y\nproperty float z\nelement face 2\n"
                                 "property list uchar int vertex_indices\nend_header\n"
                                 "0 0 0\n1 0 0\n1 1 0\n3 0 1 2\n3 0 1 9\n");
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(path);
  EXPECT_EQ(mesh.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(mesh.status().message()), HasSubstr("polygon 1 refers to vertex 9"));
}

TEST_F(MeshIoTest, AsciiPlyBodiesThatDoNotMatchTheirHeaderAreRefusedBeforeAssimp) {
  const std::string header =
      "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
      "property float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n"
      "0 0 0\n1 0 0\n0 1 0\n0 0 1\n";
  struct BadPly {
    const char* name;
    std::string text;
    const char* message;
  };
  const BadPly cases[] = {
      {"count_out_of_type", header + "3 0 1 2\n256 0 1 2\n",
       "PLY body line 6 (face 1): list count '256' is not a uchar"},
      {"count_not_a_number", header + "3 0 1 2\nx 0 1 2\n", "list count 'x' is not a uchar"},
      {"list_past_the_end", header + "3 0 1 2\n200 0 1 3\n",
       "(face 1): the line ends inside a list of 200"},
      {"truncated_vertices",
       "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
       "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
       "0 0 0\n1 0 0\n0 1 0\n0 0",
       "PLY body line 4 (vertex 3): the line ends early"},
      {"nul_in_body", header + "3 0 1 2\n3 0 1" + std::string(1, '\0') + " 3\n",
       "PLY body line 6: byte 0x00 in an ASCII file"},
      {"word_in_body", header + "3 0 1 2\n3 0 1 two\n",
       "(face 1): 'two' in a list is not a number"},
      {"word_for_a_coordinate",
       "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
       "end_header\nzero\n",
       "(vertex 0): 'zero' is not a number"},
      {"numeric_element_name",
       "ply\nformat ascii 1.0\nelement 888888888888face 2\nproperty list uchar int "
       "vertex_indices\nend_header\n0\n0\n",
       "element name '888888888888face' is not a name"},
      {"float_count_type",
       "ply\nformat ascii 1.0\nelement face 1\nproperty list float int vertex_indices\n"
       "end_header\n3 0 1 2\n",
       "a list's count type must be an integer type, found 'float'"},
  };
  for (const BadPly& bad : cases) {
    const std::string path = Write(absl::StrCat(bad.name, ".ply"), bad.text);
    absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(path);
    EXPECT_EQ(mesh.status().code(), absl::StatusCode::kInvalidArgument) << bad.name;
    EXPECT_THAT(std::string(mesh.status().message()), HasSubstr(bad.message)) << bad.name;
  }
  // fuzz_ply's 268 bytes whose list count 3555555555555555555555500 kept Assimp busy for
  // minutes (fuzz/corpus/ply/ascii_list_count_overflow.ply).
  const std::string overflow = ReadFuzzSeed("ply/ascii_list_count_overflow.ply");
  ASSERT_FALSE(overflow.empty());
  const absl::StatusOr<TriangleMesh> fuzzed = ReadMeshFile(Write("overflow.ply", overflow));
  // (It also holds bytes that are not text further on; the first problem is named.)
  EXPECT_THAT(std::string(fuzzed.status().message()),
              HasSubstr("PLY body line 5 (face 0): list count '3555555555555555555555500' is "
                        "not a uchar"));
  // The same layout with a body that matches it reads: two triangles, the tetrahedron's
  // other corners unused.
  const absl::StatusOr<TriangleMesh> good =
      ReadMeshFile(Write("good.ply", header + "3 0 1 2\n3 0 1 3\n"));
  ASSERT_TRUE(good.ok()) << good.status();
  EXPECT_EQ(good->num_faces(), 2u);
}

TEST_F(MeshIoTest, PlyHeaderProblemsAreRefusedBeforeAssimp) {
  // Each of these made Assimp 5.2's PLY reader loop forever.
  const BadOff cases[] = {
      {"truncated", "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\n",
       "no end_header line"},
      {"unknown_type", "ply\nformat ascii 1.0\nelement vertex 1\nproperty flaot x\nend_header\n0\n",
       "PLY header line 4: unknown property 'property flaot x'"},
      {"unknown_keyword", "ply\nformat ascii 1.0\nprop4rty float x\nend_header\n",
       "unknown keyword 'prop4rty'"},
      {"no_format", "ply\nelement vertex 0\nend_header\n", "no format line"},
      {"bad_element", "ply\nformat ascii 1.0\nelement vertex many\nend_header\n",
       "expected 'element NAME COUNT'"},
      // Found by fuzz_ply (the whole input is fuzz/corpus/ply/end_header_vertical_tab.ply,
      // read below): an end_header that only our tokenizer saw.
      {"vertical_tab",
       "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\v0\nelement "
       "face 1\n3 1 vvvv2 0\n",
       "PLY header line 5: control character 0x0b"},
      {"form_feed", "ply\nformat ascii 1.0\ncomment a\fb\nend_header\n",
       "PLY header line 3: control character 0x0c"},
      // Not a loop but a seek and a read per declared element: fuzz_ply's 295 bytes that
      // declared 2,222,224 faces took a minute (fuzz/corpus/ply/declares_too_many_faces.ply).
      {"declares_too_many",
       "ply\nformat ascii 1.0\nelement vertex 1000\nproperty float x\nend_header\n0\n",
       "declares more elements than the 2 bytes after it can hold"},
      {"element_without_properties", "ply\nformat ascii 1.0\nelement vertex 3\nend_header\n0\n",
       "declares more elements than the 2 bytes after it can hold"},
  };
  for (const BadOff& bad : cases) {
    const std::string path = Write(absl::StrCat(bad.name, ".ply"), bad.text);
    absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(path);
    EXPECT_EQ(mesh.status().code(), absl::StatusCode::kInvalidArgument) << bad.name;
    EXPECT_THAT(std::string(mesh.status().message()), HasSubstr(bad.message)) << bad.name;
    EXPECT_THAT(std::string(mesh.status().message()), HasSubstr(path)) << bad.name;
  }
  const std::string vertical_tab = ReadFuzzSeed("ply/end_header_vertical_tab.ply");
  ASSERT_FALSE(vertical_tab.empty());
  const std::string path = Write("fuzzer.ply", vertical_tab);
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(path);
  EXPECT_EQ(mesh.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(mesh.status().message()), HasSubstr("control character 0x0b"));
  const std::string too_many = ReadFuzzSeed("ply/declares_too_many_faces.ply");
  ASSERT_FALSE(too_many.empty());
  mesh = ReadMeshFile(Write("fuzzer2.ply", too_many));
  EXPECT_EQ(mesh.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(mesh.status().message()), HasSubstr("declares more elements"));
}

// ---------------------------------------------------------------------------------------
// Draco-compressed glTF (KHR_draco_mesh_compression).

void AppendLe32(std::string& out, uint32_t value) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<char>(value >> (8 * i)));
}

// Replaces the first `from` in `text` with `to` (which must be there).
void ReplaceOnce(std::string& text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  ASSERT_NE(at, std::string::npos) << from;
  text.replace(at, from.size(), to);
}

// A GLB with `json` and `bin` as its two chunks.
std::string MakeGlb(std::string json, std::string bin) {
  while (json.size() % 4 != 0) json.push_back(' ');
  while (bin.size() % 4 != 0) bin.push_back('\0');
  std::string glb;
  AppendLe32(glb, 0x46546C67);
  AppendLe32(glb, 2);
  AppendLe32(glb, static_cast<uint32_t>(28 + json.size() + bin.size()));
  AppendLe32(glb, static_cast<uint32_t>(json.size()));
  AppendLe32(glb, 0x4E4F534A);
  glb += json;
  AppendLe32(glb, static_cast<uint32_t>(bin.size()));
  AppendLe32(glb, 0x004E4942);
  return glb + bin;
}

// The glTF JSON of one mesh, one primitive compressed with Draco in bufferView 0 of
// buffer 0 (`buffer_json`), the POSITION attribute being Draco's attribute 0.
std::string DracoGltfJson(size_t draco_bytes, size_t num_vertices, size_t num_faces,
                          const std::string& buffer_json, const std::string& node_json) {
  return absl::StrCat(
      R"({"asset":{"version":"2.0"},"extensionsUsed":["KHR_draco_mesh_compression"],)",
      R"("extensionsRequired":["KHR_draco_mesh_compression"],"scene":0,"scenes":[{"nodes":[0]}],)",
      R"("nodes":[)", node_json, R"(],"meshes":[{"primitives":[{"attributes":{"POSITION":0},)",
      R"("indices":1,"mode":4,"extensions":{"KHR_draco_mesh_compression":{"bufferView":0,)",
      R"("attributes":{"POSITION":0}}}}]}],"accessors":[{"componentType":5126,"count":)",
      num_vertices, R"(,"type":"VEC3","min":[-1,-1,-1],"max":[1,1,1]},{"componentType":5125,)",
      R"("count":)", 3 * num_faces, R"(,"type":"SCALAR"}],"bufferViews":[{"buffer":0,)",
      R"("byteOffset":0,"byteLength":)", draco_bytes, R"(}],"buffers":[)", buffer_json, "]}");
}

TEST_F(MeshIoTest, DracoGlbReadsAsTheEncodedMesh) {
  absl::StatusOr<TriangleMesh> fandisk = ReadMeshFile(DataPath("fandisk.off"));
  ASSERT_TRUE(fandisk.ok()) << fandisk.status();
  absl::StatusOr<std::string> draco = EncodeMeshToDraco(*fandisk);
  ASSERT_TRUE(draco.ok());
  const std::string json =
      DracoGltfJson(draco->size(), fandisk->num_vertices(), fandisk->num_faces(),
                    absl::StrCat(R"({"byteLength":)", draco->size(), "}"), R"({"mesh":0})");
  const std::string path = Write("fandisk.glb", MakeGlb(json, *draco));
  absl::StatusOr<TriangleMesh> read = ReadMeshFile(path);
  ASSERT_TRUE(read.ok()) << read.status();
  // Sequential Draco keeps every order, so the file is fandisk itself, bit for bit.
  EXPECT_EQ(read->indices, fandisk->indices);
  ASSERT_EQ(read->positions.size(), fandisk->positions.size());
  EXPECT_EQ(std::memcmp(read->positions.data(), fandisk->positions.data(),
                        fandisk->positions.size() * sizeof(float)),
            0);
}

TEST_F(MeshIoTest, DracoGltfWithDataUriTransformAndAPlainMeshFromAFile) {
  // Mesh 0: an edgebreaker, 12-bit Draco grid in a data: URI, placed 10 along x. Mesh 1:
  // a plain triangle in an external .bin file, placed as it is.
  const TriangleMesh grid = Grid(5);
  DracoEncodeOptions options;
  options.method = DracoMethod::kEdgebreaker;
  options.position_quantization_bits = 12;
  absl::StatusOr<std::string> draco = EncodeMeshToDraco(grid, options);
  ASSERT_TRUE(draco.ok());
  std::string plain;
  for (float x : {0.f, 0.f, 5.f, 1.f, 0.f, 5.f, 0.f, 1.f, 5.f}) {
    AppendLe32(plain, std::bit_cast<uint32_t>(x));
  }
  for (uint32_t i : {0u, 1u, 2u}) AppendLe32(plain, i);
  Write("triangle.bin", plain);

  std::string json = DracoGltfJson(
      draco->size(), grid.num_vertices(), grid.num_faces(),
      absl::StrCat(R"({"byteLength":)", draco->size(),
                   R"(,"uri":"data:application/octet-stream;base64,)", absl::Base64Escape(*draco),
                   R"("},{"byteLength":48,"uri":"triangle.bin"})"),
      R"({"mesh":0,"translation":[10,0,0]},{"mesh":1})");
  // The second mesh: its accessors and views, and node 1 in the scene.
  ReplaceOnce(json, R"(]}],"accessors")",
              R"(]},{"primitives":[{"attributes":{"POSITION":2},"indices":3}]}],"accessors")");
  ReplaceOnce(json, R"("type":"SCALAR"}])",
              R"("type":"SCALAR"},{"componentType":5126,"count":3,"type":"VEC3",)"
              R"("bufferView":1,"min":[0,0,5],"max":[1,1,5]},{"componentType":5125,)"
              R"("count":3,"type":"SCALAR","bufferView":2}])");
  ReplaceOnce(json, R"(}],"buffers")",
              R"(},{"buffer":1,"byteOffset":0,"byteLength":36},)"
              R"({"buffer":1,"byteOffset":36,"byteLength":12}],"buffers")");
  ReplaceOnce(json, R"("nodes":[0])", R"("nodes":[0,1])");
  absl::StatusOr<TriangleMesh> read = ReadMeshFile(Write("scene.gltf", json));
  ASSERT_TRUE(read.ok()) << read.status();

  // The grid's faces first, in the order the Draco data holds them, moved by the node.
  absl::StatusOr<TriangleMesh> decoded = DecodeDracoMesh(*draco);
  ASSERT_TRUE(decoded.ok());
  for (size_t v = 0; v < decoded->num_vertices(); ++v) decoded->positions[3 * v] += 10;
  ASSERT_EQ(read->num_faces(), grid.num_faces() + 1);
  TriangleMesh grid_part = *read;
  grid_part.indices.resize(3 * grid.num_faces());
  ExpectSameFacePositions(*decoded, grid_part);
  EXPECT_EQ(CornerPosition(*read, grid.num_faces(), 1), (std::array<float, 3>{1, 0, 5}));
  EXPECT_EQ(CornerPosition(*read, grid.num_faces(), 2), (std::array<float, 3>{0, 1, 5}));
}

TEST_F(MeshIoTest, DracoGltfProblemsAreNamed) {
  const TriangleMesh grid = Grid(3);
  absl::StatusOr<std::string> draco = EncodeMeshToDraco(grid);
  ASSERT_TRUE(draco.ok());
  const std::string buffer = absl::StrCat(R"({"byteLength":)", draco->size(), "}");
  // Bytes that are not Draco.
  std::string garbage(draco->size(), 'x');
  absl::StatusOr<TriangleMesh> read = ReadMeshFile(
      Write("garbage.glb", MakeGlb(DracoGltfJson(draco->size(), grid.num_vertices(),
                                                 grid.num_faces(), buffer, R"({"mesh":0})"),
                                   garbage)));
  EXPECT_EQ(read.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(read.status().message()),
              HasSubstr("garbage.glb: mesh 0 primitive 0 (KHR_draco_mesh_compression): invalid "
                        "Draco data"));
  // An accessor count that disagrees with the Draco data.
  read = ReadMeshFile(
      Write("count.glb", MakeGlb(DracoGltfJson(draco->size(), grid.num_vertices() + 1,
                                               grid.num_faces(), buffer, R"({"mesh":0})"),
                                 *draco)));
  EXPECT_EQ(read.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(read.status().message()),
              HasSubstr("its POSITION accessor counts 17 vertices, its Draco data 16"));
  // A bufferView past the end of its buffer.
  read = ReadMeshFile(
      Write("short.glb", MakeGlb(DracoGltfJson(draco->size() + 100, grid.num_vertices(),
                                               grid.num_faces(), buffer, R"({"mesh":0})"),
                                 *draco)));
  EXPECT_EQ(read.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(read.status().message()), HasSubstr("outside its buffer"));
  // JSON with a member of the wrong type.
  std::string json =
      DracoGltfJson(draco->size(), grid.num_vertices(), grid.num_faces(), buffer, R"({"mesh":0})");
  ReplaceOnce(json, R"("bufferView":0,)", R"("bufferView":"zero",)");
  read = ReadMeshFile(Write("type.glb", MakeGlb(json, *draco)));
  EXPECT_EQ(read.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(read.status().message()), HasSubstr("type.glb: glTF JSON"));
}

// ---------------------------------------------------------------------------------------
// Clustered PLY output and colours.

// A binary little-endian PLY read by its header alone (float, uchar, int scalars and
// "list uchar int" lists), so that the tests check what the header promises.
struct ParsedPly {
  struct Element {
    std::string name;
    size_t count = 0;
    std::vector<std::pair<std::string, std::string>> properties;  // (type, name)
    std::vector<std::map<std::string, std::vector<double>>> records;
  };
  std::vector<Element> elements;
  const Element* Find(const std::string& name) const {
    for (const Element& e : elements) {
      if (e.name == name) return &e;
    }
    return nullptr;
  }
};

ParsedPly ParsePly(const std::string& bytes) {
  ParsedPly ply;
  const std::string header_end = "end_header\n";
  const size_t body = bytes.find(header_end);
  EXPECT_NE(body, std::string::npos);
  std::istringstream header(bytes.substr(0, body));
  std::string line;
  while (std::getline(header, line)) {
    std::istringstream words(line);
    std::string word;
    words >> word;
    if (word == "element") {
      ParsedPly::Element element;
      words >> element.name >> element.count;
      ply.elements.push_back(element);
    } else if (word == "property") {
      std::string type, name;
      words >> type;
      if (type == "list") {
        std::string count_type, item_type;
        words >> count_type >> item_type;
        EXPECT_EQ(count_type + " " + item_type, "uchar int");
      }
      words >> name;
      ply.elements.back().properties.push_back({type, name});
    }
  }
  size_t at = body + header_end.size();
  auto take = [&](size_t n) {
    EXPECT_LE(at + n, bytes.size());
    const char* p = bytes.data() + std::min(at, bytes.size() - n);
    at += n;
    return p;
  };
  for (ParsedPly::Element& element : ply.elements) {
    for (size_t r = 0; r < element.count; ++r) {
      std::map<std::string, std::vector<double>> record;
      for (const auto& [type, name] : element.properties) {
        if (type == "float") {
          record[name] = {std::bit_cast<float>(*reinterpret_cast<const uint32_t*>(take(4)))};
        } else if (type == "int") {
          int32_t value;
          std::memcpy(&value, take(4), 4);
          record[name] = {static_cast<double>(value)};
        } else if (type == "uchar") {
          record[name] = {static_cast<double>(static_cast<uint8_t>(*take(1)))};
        } else {
          EXPECT_EQ(type, "list");
          const uint8_t n = static_cast<uint8_t>(*take(1));
          for (uint8_t i = 0; i < n; ++i) {
            int32_t value;
            std::memcpy(&value, take(4), 4);
            record[name].push_back(value);
          }
        }
      }
      element.records.push_back(std::move(record));
    }
  }
  EXPECT_EQ(at, bytes.size()) << "bytes after the last element";
  return ply;
}

// A 4 x 4 grid: the left two columns of squares are cluster 7, the rest cluster 2, and
// the last face is unlabelled.
std::vector<ClusterId> GridTwoClusterLabels(const TriangleMesh& mesh) {
  std::vector<ClusterId> labels;
  for (size_t f = 0; f < mesh.num_faces(); ++f) {
    const size_t column = (f / 2) % 4;
    labels.push_back(ClusterId(column < 2 ? 7 : 2));
  }
  labels[31] = ClusterId::Invalid();  // Top right square's second triangle: (c, b, d).
  return labels;
}

TEST_F(MeshIoTest, ClusteredPlyKeepsVerticesAndCarriesClusterIdsAndColours) {
  TriangleMesh mesh = Grid(4);
  // An unused vertex stays, so that vertex ids are the input's.
  mesh.positions.insert(mesh.positions.end(), {9.5f, -1.25f, 3.0f});
  const std::vector<ClusterId> labels = GridTwoClusterLabels(mesh);
  const std::string path = Path("clusters.ply");
  ASSERT_TRUE(WriteClusteredPly(path, mesh, labels).ok());

  const ParsedPly ply = ParsePly(ReadFileBytes(path));
  ASSERT_EQ(ply.elements.size(), 2u);
  const ParsedPly::Element* vertex = ply.Find("vertex");
  const ParsedPly::Element* face = ply.Find("face");
  ASSERT_NE(vertex, nullptr);
  ASSERT_NE(face, nullptr);
  ASSERT_EQ(vertex->count, mesh.num_vertices());
  ASSERT_EQ(vertex->properties.size(), 3u);  // x, y, z: no colour on shared vertices.
  for (size_t v = 0; v < mesh.num_vertices(); ++v) {
    EXPECT_EQ(vertex->records[v].at("x")[0], mesh.positions[3 * v]);
    EXPECT_EQ(vertex->records[v].at("y")[0], mesh.positions[3 * v + 1]);
    EXPECT_EQ(vertex->records[v].at("z")[0], mesh.positions[3 * v + 2]);
  }
  ASSERT_EQ(face->count, mesh.num_faces());
  for (size_t f = 0; f < mesh.num_faces(); ++f) {
    const auto& record = face->records[f];
    const std::vector<double> corners = {double(mesh.indices[3 * f]),
                                         double(mesh.indices[3 * f + 1]),
                                         double(mesh.indices[3 * f + 2])};
    EXPECT_EQ(record.at("vertex_indices"), corners) << "face " << f;
    EXPECT_EQ(record.at("cluster")[0], labels[f].valid() ? double(labels[f].value()) : -1.0)
        << "face " << f;
    const std::array<uint8_t, 3> want = labels[f].valid() ? ClusterColour(labels[f].value())
                                                          : std::array<uint8_t, 3>{128, 128, 128};
    EXPECT_EQ(record.at("red")[0], want[0]) << "face " << f;
    EXPECT_EQ(record.at("green")[0], want[1]) << "face " << f;
    EXPECT_EQ(record.at("blue")[0], want[2]) << "face " << f;
  }

  // Our reader (Assimp for PLY) reads it back as the same mesh.
  absl::StatusOr<TriangleMesh> read = ReadMeshFile(path);
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->num_vertices(), mesh.num_vertices());
  EXPECT_EQ(read->indices, mesh.indices);
}

TEST_F(MeshIoTest, ClusteredPlySplitVerticesForVertexColours) {
  // The 5 vertices on the column boundary x = 2 appear twice; the unlabelled face adds a
  // copy of each of its corners (one of which, the grid's corner (4, 4), no other face
  // uses).
  const TriangleMesh mesh = Grid(4);
  const std::vector<ClusterId> labels = GridTwoClusterLabels(mesh);
  std::set<std::pair<uint32_t, uint32_t>> pairs;
  for (size_t i = 0; i < mesh.indices.size(); ++i) {
    pairs.insert({mesh.indices[i], labels[i / 3].value()});
  }
  ASSERT_EQ(pairs.size(), 24u + 5u + 3u);

  const std::string path = Path("clusters.ply");
  ASSERT_TRUE(WriteClusteredPly(path, mesh, labels, {.split_vertices = true}).ok());
  const ParsedPly ply = ParsePly(ReadFileBytes(path));
  ASSERT_NE(ply.Find("vertex"), nullptr);
  ASSERT_NE(ply.Find("face"), nullptr);
  EXPECT_EQ(ply.Find("vertex")->count, pairs.size());
  for (size_t f = 0; f < mesh.num_faces(); ++f) {
    EXPECT_EQ(ply.Find("face")->records[f].at("cluster")[0],
              labels[f].valid() ? double(labels[f].value()) : -1.0);
  }

  // Assimp reads it back with the same faces and the split vertices.
  absl::StatusOr<TriangleMesh> read = ReadMeshFile(path);
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->num_vertices(), pairs.size());
  ExpectSameFacePositions(mesh, *read);

  // Its vertex colours are the clusters' colours.
  Assimp::Importer importer;
  const aiScene* scene = importer.ReadFile(path, 0);
  ASSERT_NE(scene, nullptr) << importer.GetErrorString();
  ASSERT_EQ(scene->mNumMeshes, 1u);
  const aiMesh& ai = *scene->mMeshes[0];
  ASSERT_NE(ai.mColors[0], nullptr);
  ASSERT_EQ(ai.mNumFaces, 32u);
  for (unsigned f = 0; f < ai.mNumFaces; ++f) {
    const std::array<uint8_t, 3> want = labels[f].valid() ? ClusterColour(labels[f].value())
                                                          : std::array<uint8_t, 3>{128, 128, 128};
    for (unsigned c = 0; c < 3; ++c) {
      const aiColor4D& got = ai.mColors[0][ai.mFaces[f].mIndices[c]];
      EXPECT_EQ(std::lround(got.r * 255), want[0]) << "face " << f;
      EXPECT_EQ(std::lround(got.g * 255), want[1]) << "face " << f;
      EXPECT_EQ(std::lround(got.b * 255), want[2]) << "face " << f;
    }
  }
}

// The JSON and the buffer of a glTF file WriteClusteredGltf wrote (.glb or .gltf).
std::pair<nlohmann::json, std::string> ReadGltfParts(const std::string& bytes) {
  if (bytes.starts_with("glTF")) {
    uint32_t json_length;
    std::memcpy(&json_length, &bytes[12], 4);
    nlohmann::json json = nlohmann::json::parse(bytes.substr(20, json_length));
    uint32_t bin_length;
    std::memcpy(&bin_length, &bytes[20 + json_length], 4);
    return {json, bytes.substr(28 + json_length, bin_length)};
  }
  nlohmann::json json = nlohmann::json::parse(bytes);
  const std::string uri = json["buffers"][0]["uri"];
  std::string bin;
  EXPECT_TRUE(absl::Base64Unescape(uri.substr(uri.find(',') + 1), &bin));
  return {json, bin};
}

TEST_F(MeshIoTest, ClusteredGltfCarriesClusterIdsAndColoursPerFace) {
  const TriangleMesh mesh = Grid(4);
  const std::vector<ClusterId> labels = GridTwoClusterLabels(mesh);
  for (const std::string name : {"clusters.glb", "clusters.gltf"}) {
    SCOPED_TRACE(name);
    const std::string path = Path(name);
    ASSERT_TRUE(WriteClusteredGltf(path, mesh, labels).ok());
    const auto [json, bin] = ReadGltfParts(ReadFileBytes(path));
    EXPECT_EQ(json["scenes"][0]["nodes"], nlohmann::json::array({0}));
    EXPECT_EQ(json["nodes"][0]["mesh"], 0);
    const nlohmann::json& primitive = json["meshes"][0]["primitives"][0];
    ASSERT_EQ(primitive["attributes"].size(), 3u);
    auto accessor_data = [&](int accessor, size_t element_bytes) {
      const nlohmann::json& a = json["accessors"][accessor];
      const nlohmann::json& v = json["bufferViews"][a["bufferView"].get<int>()];
      EXPECT_EQ(v["byteLength"].get<size_t>(), a["count"].get<size_t>() * element_bytes);
      return bin.substr(v["byteOffset"].get<size_t>(), v["byteLength"].get<size_t>());
    };
    const std::string positions = accessor_data(primitive["attributes"]["POSITION"], 12);
    const std::string colours = accessor_data(primitive["attributes"]["COLOR_0"], 4);
    const std::string clusters = accessor_data(primitive["attributes"]["_CLUSTER"], 4);
    const std::string indices = accessor_data(primitive["indices"], 4);
    EXPECT_EQ(json["accessors"][primitive["attributes"]["_CLUSTER"].get<int>()]["componentType"],
              5126);
    ASSERT_EQ(indices.size(), mesh.indices.size() * 4);
    // The same boundary vertices are doubled as in the split PLY: 24 + 5 + 3 copies.
    EXPECT_EQ(positions.size() / 12, 24u + 5u + 3u);
    for (size_t f = 0; f < mesh.num_faces(); ++f) {
      const float want = labels[f].valid() ? static_cast<float>(labels[f].value()) : -1.0f;
      const std::array<uint8_t, 3> colour = labels[f].valid()
                                                ? ClusterColour(labels[f].value())
                                                : std::array<uint8_t, 3>{128, 128, 128};
      for (int c = 0; c < 3; ++c) {
        uint32_t vertex;
        std::memcpy(&vertex, &indices[4 * (3 * f + c)], 4);
        float cluster;
        std::memcpy(&cluster, &clusters[4 * vertex], 4);
        EXPECT_EQ(cluster, want) << "face " << f;
        EXPECT_EQ(std::memcmp(&colours[4 * vertex], colour.data(), 3), 0) << "face " << f;
        EXPECT_EQ(static_cast<uint8_t>(colours[4 * vertex + 3]), 255);
        // Bit for bit the input's corner.
        EXPECT_EQ(
            std::memcmp(&positions[12 * vertex], &mesh.positions[3 * mesh.indices[3 * f + c]], 12),
            0);
      }
    }
    // Our reader (Assimp) reads the faces back in order.
    absl::StatusOr<TriangleMesh> read = ReadMeshFile(path);
    ASSERT_TRUE(read.ok()) << read.status();
    ExpectSameFacePositions(mesh, *read);
  }
  EXPECT_EQ(WriteClusteredGltf(Path("clusters.obj"), mesh, labels).code(),
            absl::StatusCode::kInvalidArgument);
  std::vector<ClusterId> big = labels;
  big[3] = ClusterId(1u << 24);
  const absl::Status status = WriteClusteredGltf(Path("big.glb"), mesh, big);
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(status.message()), HasSubstr("face 3: cluster id 16777216"));
}

TEST_F(MeshIoTest, ClusteredPlyRefusesWrongLabelCountAndBadIndices) {
  const TriangleMesh mesh = Tetrahedron();
  std::vector<ClusterId> three(3, ClusterId(0));
  absl::Status status = WriteClusteredPly(Path("a.ply"), mesh, three);
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(status.message()), HasSubstr("got 3 labels for 4 faces"));

  TriangleMesh broken = mesh;
  broken.indices[5] = 9;
  std::vector<ClusterId> four(4, ClusterId(0));
  status = WriteClusteredPly(Path("b.ply"), broken, four);
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(status.message()),
              HasSubstr("face 1 corner 2: vertex index 9 is out of range"));

  status = WriteClusteredPly(Path("no/such/folder/c.ply"), mesh, four);
  EXPECT_FALSE(status.ok());
  EXPECT_THAT(std::string(status.message()), HasSubstr("no/such/folder/c.ply"));
}

TEST(ClusterColourTest, StableSpreadAndDistinctForNeighbours) {
  // Id 0 has hue 0: pure red at saturation 0.65, value 0.95.
  EXPECT_EQ(ClusterColour(0), (std::array<uint8_t, 3>{242, 85, 85}));
  EXPECT_EQ(ClusterColour(12345), ClusterColour(12345));
  std::set<std::array<uint8_t, 3>> first_hundred;
  for (uint32_t id = 0; id < 100; ++id) first_hundred.insert(ClusterColour(id));
  EXPECT_EQ(first_hundred.size(), 100u);
  // Consecutive ids are 137.5 degrees of hue apart: clearly different colours.
  for (uint32_t id = 0; id < 10000; ++id) {
    const auto a = ClusterColour(id), b = ClusterColour(id + 1);
    int largest = 0;
    for (int c = 0; c < 3; ++c) largest = std::max(largest, std::abs(a[c] - b[c]));
    EXPECT_GE(largest, 100) << "ids " << id << " and " << id + 1;
  }
}

}  // namespace
}  // namespace mlclust

namespace mlclust {
namespace {

TEST(WriteMeshFileTest, RoundTripsThroughOurReaders) {
  absl::StatusOr<TriangleMesh> fandisk = ReadMeshFile(testing::DataPath("fandisk.off"));
  ASSERT_TRUE(fandisk.ok());
  for (const char* extension : {".ply", ".off", ".obj"}) {
    const std::string path = ::testing::TempDir() + "/roundtrip" + extension;
    ASSERT_TRUE(WriteMeshFile(path, *fandisk).ok()) << extension;
    absl::StatusOr<TriangleMesh> back = ReadMeshFile(path);
    ASSERT_TRUE(back.ok()) << extension << ": " << back.status();
    ASSERT_EQ(back->num_faces(), fandisk->num_faces()) << extension;
    // Every face has the same three corner positions in the same order.
    for (size_t f = 0; f < fandisk->num_faces(); f += 97) {
      for (int c = 0; c < 3; ++c) {
        const Vec3 a = fandisk->position(fandisk->corner(FaceId(f), c));
        const Vec3 b = back->position(back->corner(FaceId(f), c));
        EXPECT_NEAR(a.x, b.x, 1e-6) << extension;
        EXPECT_NEAR(a.y, b.y, 1e-6) << extension;
        EXPECT_NEAR(a.z, b.z, 1e-6) << extension;
      }
    }
  }
  EXPECT_EQ(WriteMeshFile(::testing::TempDir() + "/x.stl", *fandisk).code(),
            absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace mlclust
