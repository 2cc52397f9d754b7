#include "core/meshlets/meshlets.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "core/io/mesh_io.h"
#include "core/meshlets/meshlet_file.h"
#include "core/meshlets/meshlet_gltf.h"
#include "nlohmann/json.hpp"
#include "tests/fixtures/test_meshes.h"

namespace mlclust {
namespace {

using testing::MakeMesh;

// Edge-connected pieces of each meshlet, from an edge map of our own (an edge shared by
// any number of faces connects them all): the count of meshlets in more than one piece.
uint32_t DisconnectedMeshlets(const TriangleMesh& mesh, const std::vector<uint32_t>& label) {
  std::map<std::pair<uint32_t, uint32_t>, std::vector<uint32_t>> edges;
  for (uint32_t f = 0; f < mesh.num_faces(); ++f) {
    for (int i = 0; i < 3; ++i) {
      uint32_t a = mesh.indices[3 * f + i], b = mesh.indices[3 * f + (i + 1) % 3];
      if (a == b) continue;
      if (a > b) std::swap(a, b);
      edges[{a, b}].push_back(f);
    }
  }
  std::vector<uint32_t> root(mesh.num_faces());
  for (uint32_t f = 0; f < root.size(); ++f) root[f] = f;
  auto find = [&](uint32_t f) {
    while (root[f] != f) f = root[f] = root[root[f]];
    return f;
  };
  for (const auto& [edge, faces] : edges) {
    for (size_t i = 1; i < faces.size(); ++i) {
      for (size_t j = 0; j < i; ++j) {
        if (label[faces[i]] == label[faces[j]]) root[find(faces[i])] = find(faces[j]);
      }
    }
  }
  std::map<uint32_t, std::vector<uint32_t>> roots;  // meshlet -> its pieces' roots
  for (uint32_t f = 0; f < mesh.num_faces(); ++f) {
    std::vector<uint32_t>& r = roots[label[f]];
    if (std::find(r.begin(), r.end(), find(f)) == r.end()) r.push_back(find(f));
  }
  uint32_t disconnected = 0;
  for (const auto& [meshlet, pieces] : roots) disconnected += pieces.size() > 1 ? 1 : 0;
  return disconnected;
}

// Builds with these caps and checks everything a consumer relies on; returns the result.
MeshletResult BuildAndCheck(const TriangleMesh& mesh, uint32_t max_vertices, uint32_t max_triangles,
                            float cone_weight = 0) {
  MeshletOptions options;
  options.max_vertices = max_vertices;
  options.max_triangles = max_triangles;
  options.cone_weight = cone_weight;
  absl::StatusOr<MeshletResult> result = BuildMeshlets(mesh, options);
  EXPECT_TRUE(result.ok()) << result.status();
  if (!result.ok()) return {};
  EXPECT_TRUE(CheckMeshletLayout(*result, max_vertices, max_triangles, &mesh).ok())
      << CheckMeshletLayout(*result, max_vertices, max_triangles, &mesh);
  for (const Meshlet& meshlet : result->meshlets) {
    EXPECT_LE(meshlet.vertex_count, max_vertices);
    EXPECT_LE(meshlet.triangle_count, max_triangles);
  }
  EXPECT_EQ(DisconnectedMeshlets(mesh, result->face_meshlet), 0u);
  // Each bounding sphere holds its meshlet's vertices.
  EXPECT_EQ(result->bounds.size(), result->meshlets.size());
  for (size_t m = 0; m < result->bounds.size() && m < result->meshlets.size(); ++m) {
    const MeshletBounds& b = result->bounds[m];
    const Meshlet& meshlet = result->meshlets[m];
    for (uint32_t i = 0; i < meshlet.vertex_count; ++i) {
      const Vec3 p = mesh.position(VertexId(result->meshlet_vertices[meshlet.vertex_offset + i]));
      const double d = std::sqrt((p.x - b.center[0]) * (p.x - b.center[0]) +
                                 (p.y - b.center[1]) * (p.y - b.center[1]) +
                                 (p.z - b.center[2]) * (p.z - b.center[2]));
      // meshoptimizer works in float: allow its rounding at this distance from the origin.
      const double magnitude = std::sqrt(p.x * p.x + p.y * p.y + p.z * p.z);
      EXPECT_LE(d, b.radius * (1 + 1e-4) + 1e-6 * (1 + magnitude)) << "meshlet " << m;
    }
  }
  return *std::move(result);
}

// A closed fan: `spokes` triangles around vertex 0, each between rim vertices i and i + 1.
TriangleMesh Fan(uint32_t spokes) {
  TriangleMesh mesh;
  mesh.positions = {0, 0, 0};
  for (uint32_t i = 0; i < spokes; ++i) {
    const double angle = 2 * 3.14159265358979 * i / spokes;
    mesh.positions.insert(mesh.positions.end(), {static_cast<float>(std::cos(angle)),
                                                 static_cast<float>(std::sin(angle)), 0.0f});
  }
  for (uint32_t i = 0; i < spokes; ++i) {
    mesh.indices.insert(mesh.indices.end(), {0, 1 + i, 1 + (i + 1) % spokes});
  }
  return mesh;
}

// A strip of `quads` unit squares, two triangles each, two vertices wide.
TriangleMesh Strip(uint32_t quads) {
  TriangleMesh mesh;
  for (uint32_t i = 0; i <= quads; ++i) {
    mesh.positions.insert(mesh.positions.end(), {static_cast<float>(i), 0, 0});
    mesh.positions.insert(mesh.positions.end(), {static_cast<float>(i), 1e-3f, 0});
  }
  for (uint32_t i = 0; i < quads; ++i) {
    const uint32_t a = 2 * i, b = a + 1, c = a + 2, d = a + 3;
    mesh.indices.insert(mesh.indices.end(), {a, c, b, b, c, d});
  }
  return mesh;
}

// `pieces` separate triangles, each its own three vertices.
TriangleMesh SeparateTriangles(uint32_t pieces) {
  TriangleMesh mesh;
  for (uint32_t i = 0; i < pieces; ++i) {
    const uint32_t column = i % 40, row = i / 40;
    const auto x = static_cast<float>(column), y = static_cast<float>(row);
    mesh.positions.insert(mesh.positions.end(), {x, y, 0, x + 0.5f, y, 0, x, y + 0.5f, 0});
    mesh.indices.insert(mesh.indices.end(), {3 * i, 3 * i + 1, 3 * i + 2});
  }
  return mesh;
}

// `pages` triangles sharing the edge (0, 1): a non-manifold edge (a book).
TriangleMesh Book(uint32_t pages) {
  TriangleMesh mesh;
  mesh.positions = {0, 0, 0, 0, 0, 1};
  for (uint32_t i = 0; i < pages; ++i) {
    const double angle = 2 * 3.14159265358979 * i / pages;
    mesh.positions.insert(mesh.positions.end(), {static_cast<float>(std::cos(angle)),
                                                 static_cast<float>(std::sin(angle)), 0.5f});
    mesh.indices.insert(mesh.indices.end(), {0, 1, 2 + i});
  }
  return mesh;
}

TEST(BuildMeshlets, TetrahedronIsOneMeshlet) {
  const TriangleMesh mesh = testing::Tetrahedron();
  const MeshletResult result = BuildAndCheck(mesh, 64, 124);
  ASSERT_EQ(result.meshlets.size(), 1u);
  EXPECT_EQ(result.meshlets[0].vertex_count, 4u);
  EXPECT_EQ(result.meshlets[0].triangle_count, 4u);
  EXPECT_EQ(result.meshlet_triangles.size(), 12u);  // 12 bytes: already a multiple of 4
  EXPECT_EQ(result.face_meshlet, (std::vector<uint32_t>{0, 0, 0, 0}));
}

TEST(BuildMeshlets, ThreeVerticesAllowOneTriangleEach) {
  const MeshletResult result = BuildAndCheck(testing::TwoTriangles(), 3, 124);
  ASSERT_EQ(result.meshlets.size(), 2u);
  EXPECT_EQ(result.meshlets[0].vertex_count, 3u);
  EXPECT_EQ(result.meshlets[1].vertex_count, 3u);
  // Each run of 3 bytes padded to 4.
  EXPECT_EQ(result.meshlets[1].triangle_offset, 4u);
  EXPECT_EQ(result.meshlet_triangles.size(), 8u);
}

TEST(BuildMeshlets, KeepsTheWinding) {
  const TriangleMesh mesh = testing::TwoTriangles();
  const MeshletResult result = BuildAndCheck(mesh, 64, 124);
  ASSERT_EQ(result.meshlets.size(), 1u);
  for (uint32_t t = 0; t < 2; ++t) {
    const uint32_t face = result.triangle_faces[t];
    for (int corner = 0; corner < 3; ++corner) {
      EXPECT_EQ(result.meshlet_vertices[result.meshlet_triangles[3 * t + corner]],
                mesh.indices[3 * face + corner]);
    }
  }
}

TEST(BuildMeshlets, NeverJoinsPiecesThatOnlyTouchAtAVertex) {
  // Both triangles fit in one meshlet, but they share no edge.
  const MeshletResult result = BuildAndCheck(testing::BowTie(), 64, 124);
  EXPECT_EQ(result.meshlets.size(), 2u);
}

TEST(BuildMeshlets, AThousandSeparatePiecesGiveAThousandMeshlets) {
  const TriangleMesh mesh = SeparateTriangles(1000);
  const MeshletResult result = BuildAndCheck(mesh, 64, 124);
  EXPECT_EQ(result.meshlets.size(), 1000u);
}

TEST(BuildMeshlets, FanOfDegreeAThousand) {
  // An arc of k fan triangles has k + 2 vertices: 62 triangles at 64 vertices, so 1,000
  // triangles need 17 meshlets at least.
  const TriangleMesh mesh = Fan(1000);
  const MeshletResult result = BuildAndCheck(mesh, 64, 124);
  EXPECT_EQ(result.meshlets.size(), 17u);  // the bound, reached
  uint32_t at_cap = 0;
  for (const Meshlet& meshlet : result.meshlets) at_cap += meshlet.vertex_count == 64 ? 1 : 0;
  EXPECT_GE(at_cap, 15u);
  BuildAndCheck(mesh, 3, 1);
  BuildAndCheck(mesh, 255, 512);
}

TEST(BuildMeshlets, LongThinStrip) {
  // k quads of a strip have 2 k + 2 vertices: 31 quads (62 triangles) at 64 vertices.
  const TriangleMesh mesh = Strip(5000);
  const MeshletResult result = BuildAndCheck(mesh, 64, 124);
  EXPECT_EQ(result.meshlets.size(), 162u);  // ceil(10,000 / 62), the bound, reached
  BuildAndCheck(mesh, 4, 2);
  BuildAndCheck(mesh, 255, 512);
}

TEST(BuildMeshlets, NonManifoldEdgeConnectsAllItsFaces) {
  const TriangleMesh book = Book(5);
  const MeshletResult one = BuildAndCheck(book, 64, 124);
  ASSERT_EQ(one.meshlets.size(), 1u);
  EXPECT_EQ(one.meshlets[0].vertex_count, 7u);
  const MeshletResult capped = BuildAndCheck(book, 64, 2);
  EXPECT_EQ(capped.meshlets.size(), 3u);
}

TEST(BuildMeshlets, NonManifoldGridWithBooksAlongItsEdges) {
  // A 30 x 30 grid whose every fifth row edge also carries a third, upright triangle.
  TriangleMesh mesh = testing::Grid(30);
  const uint32_t first_extra = static_cast<uint32_t>(mesh.num_vertices());
  for (uint32_t x = 0; x < 30; x += 5) {
    const uint32_t a = 5 * 31 + x, b = a + 1;
    const uint32_t top = static_cast<uint32_t>(mesh.num_vertices());
    mesh.positions.insert(mesh.positions.end(), {x + 0.5f, 5.0f, 1.0f});
    mesh.indices.insert(mesh.indices.end(), {a, b, top});
  }
  ASSERT_FALSE(ValidateMesh(mesh).ok());  // non-manifold, as intended
  ASSERT_GT(mesh.num_vertices(), first_extra);
  for (const auto& [v, t] : std::vector<std::pair<uint32_t, uint32_t>>{
           {64, 124}, {3, 1}, {16, 8}, {32, 64}, {255, 512}}) {
    BuildAndCheck(mesh, v, t);
  }
}

TEST(BuildMeshlets, AcceptsDegenerateFaces) {
  TriangleMesh mesh = testing::TwoTriangles();
  mesh.indices.insert(mesh.indices.end(), {1, 1, 2, 3, 3, 3});
  const MeshletResult result = BuildAndCheck(mesh, 64, 124);
  EXPECT_EQ(result.face_meshlet.size(), 4u);
}

TEST(BuildMeshlets, CapsHoldOnTheDataMeshes) {
  const std::vector<std::string> paths = {
      testing::DataPath("elephant.off"), testing::DataPath("elephant-with-holes.off"),
      testing::DataPath("fandisk.off"),
      testing::DataPath("../tests/fixtures/cgal_double_torus_example.off"),
      testing::DataPath("../tests/fixtures/cgal_polygon_mesh_crop.off")};
  for (const std::string& path : paths) {
    SCOPED_TRACE(path);
    absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(path);
    ASSERT_TRUE(mesh.ok()) << mesh.status();
    for (const auto& [v, t] : std::vector<std::pair<uint32_t, uint32_t>>{
             {64, 124}, {3, 1}, {10, 4}, {32, 60}, {128, 256}, {255, 512}}) {
      SCOPED_TRACE(::testing::Message() << v << " vertices, " << t << " triangles");
      BuildAndCheck(*mesh, v, t, 0.0f);
    }
    BuildAndCheck(*mesh, 64, 124, 0.25f);
    BuildAndCheck(*mesh, 64, 124, 1.0f);
  }
}

TEST(BuildMeshlets, FillsAGridToTheVertexCap) {
  // A 60 x 60 grid (7,200 triangles): the meshlets are compact, most at the vertex cap.
  const TriangleMesh mesh = testing::Grid(60);
  const MeshletResult result = BuildAndCheck(mesh, 64, 124);
  uint32_t at_cap = 0;
  for (const Meshlet& meshlet : result.meshlets) at_cap += meshlet.vertex_count == 64 ? 1 : 0;
  EXPECT_GE(at_cap * 10, result.meshlets.size() * 8);  // 80 % at least
  // 7,200 triangles in fewer than 7,200 / 90 meshlets.
  EXPECT_LT(result.meshlets.size(), 80u);
}

TEST(BuildMeshlets, IsDeterministic) {
  const TriangleMesh mesh = testing::Grid(40, {5, 77, 300});
  const MeshletResult a = BuildAndCheck(mesh, 64, 124, 0.25f);
  const MeshletResult b = BuildAndCheck(mesh, 64, 124, 0.25f);
  EXPECT_EQ(a.face_meshlet, b.face_meshlet);
  EXPECT_EQ(a.meshlet_triangles, b.meshlet_triangles);
  EXPECT_EQ(a.meshlet_vertices, b.meshlet_vertices);
}

TEST(BuildMeshlets, WithoutBounds) {
  MeshletOptions options;
  options.compute_bounds = false;
  absl::StatusOr<MeshletResult> result = BuildMeshlets(testing::Grid(4), options);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_TRUE(result->bounds.empty());
}

TEST(BuildMeshlets, RejectsBadOptions) {
  const TriangleMesh mesh = testing::TwoTriangles();
  for (const auto& [v, t] :
       std::vector<std::pair<uint32_t, uint32_t>>{{2, 124}, {256, 124}, {64, 0}, {64, 513}}) {
    MeshletOptions options;
    options.max_vertices = v;
    options.max_triangles = t;
    absl::StatusOr<MeshletResult> result = BuildMeshlets(mesh, options);
    EXPECT_EQ(result.status().code(), absl::StatusCode::kInvalidArgument) << v << " " << t;
  }
  MeshletOptions cone;
  cone.cone_weight = -0.5f;
  EXPECT_EQ(BuildMeshlets(mesh, cone).status().code(), absl::StatusCode::kInvalidArgument);
}

TEST(BuildMeshlets, RejectsBadMeshes) {
  TriangleMesh out_of_range = testing::TwoTriangles();
  out_of_range.indices[4] = 9;
  absl::StatusOr<MeshletResult> a = BuildMeshlets(out_of_range);
  EXPECT_EQ(a.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(a.status().message().find("face 1"), std::string::npos) << a.status();
  TriangleMesh not_finite = testing::TwoTriangles();
  not_finite.positions[7] = std::nanf("");
  absl::StatusOr<MeshletResult> b = BuildMeshlets(not_finite);
  EXPECT_EQ(b.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(b.status().message().find("vertex 2"), std::string::npos) << b.status();
  EXPECT_EQ(BuildMeshlets(MakeMesh({0, 0, 0}, {})).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(BuildMeshlets(MakeMesh({0, 0, 0, 1, 0, 0}, {0, 1})).status().code(),
            absl::StatusCode::kInvalidArgument);
}

TEST(BuildMeshlets, Cancels) {
  std::atomic<bool> cancel{true};
  MeshletOptions options;
  options.cancel = &cancel;
  EXPECT_EQ(BuildMeshlets(testing::Grid(10), options).status().code(),
            absl::StatusCode::kCancelled);
}

TEST(CheckMeshletLayout, FindsBrokenLayouts) {
  const TriangleMesh mesh = testing::Grid(6);
  const MeshletResult good = BuildAndCheck(mesh, 16, 16);
  ASSERT_GT(good.meshlets.size(), 1u);
  MeshletResult local = good;
  local.meshlet_triangles[0] = static_cast<uint8_t>(local.meshlets[0].vertex_count);
  EXPECT_FALSE(CheckMeshletLayout(local, 16, 16, &mesh).ok());
  MeshletResult twice = good;
  twice.triangle_faces[1] = twice.triangle_faces[0];
  EXPECT_FALSE(CheckMeshletLayout(twice, 16, 16, &mesh).ok());
  MeshletResult offset = good;
  offset.meshlets[1].vertex_offset += 1;
  EXPECT_FALSE(CheckMeshletLayout(offset, 16, 16, &mesh).ok());
  uint32_t most = 0;
  for (const Meshlet& meshlet : good.meshlets) most = std::max(most, meshlet.vertex_count);
  EXPECT_FALSE(CheckMeshletLayout(good, most - 1, 16, &mesh).ok());  // a cap they exceed
  MeshletResult corner = good;
  std::swap(corner.meshlet_triangles[0], corner.meshlet_triangles[1]);
  EXPECT_FALSE(CheckMeshletLayout(corner, 16, 16, &mesh).ok());
  EXPECT_TRUE(CheckMeshletLayout(corner, 16, 16).ok());  // without the mesh, corners unchecked
}

TEST(MeshletFile, RoundTrips) {
  const TriangleMesh mesh = testing::Grid(12, {3, 40});
  const MeshletResult built = BuildAndCheck(mesh, 32, 40, 0.25f);
  absl::StatusOr<std::string> bytes =
      EncodeMeshletFile(built, static_cast<uint32_t>(mesh.num_vertices()), 32, 40);
  ASSERT_TRUE(bytes.ok()) << bytes.status();
  EXPECT_EQ(bytes->size(), 64 + 16 * built.meshlets.size() + 4 * built.meshlet_vertices.size() +
                               built.meshlet_triangles.size() + 4 * mesh.num_faces() +
                               48 * built.meshlets.size());
  EXPECT_EQ(bytes->substr(0, 8), "MLCMSHLT");
  absl::StatusOr<MeshletFile> file = DecodeMeshletFile(*bytes);
  ASSERT_TRUE(file.ok()) << file.status();
  EXPECT_EQ(file->max_vertices, 32u);
  EXPECT_EQ(file->max_triangles, 40u);
  EXPECT_EQ(file->vertex_count, mesh.num_vertices());
  EXPECT_EQ(file->meshlets.face_meshlet, built.face_meshlet);
  EXPECT_EQ(file->meshlets.meshlet_vertices, built.meshlet_vertices);
  EXPECT_EQ(file->meshlets.meshlet_triangles, built.meshlet_triangles);
  EXPECT_EQ(file->meshlets.triangle_faces, built.triangle_faces);
  ASSERT_EQ(file->meshlets.bounds.size(), built.bounds.size());
  for (size_t m = 0; m < built.bounds.size(); ++m) {
    EXPECT_EQ(file->meshlets.bounds[m].radius, built.bounds[m].radius);
    EXPECT_EQ(file->meshlets.bounds[m].cone_cutoff_s8, built.bounds[m].cone_cutoff_s8);
    EXPECT_EQ(file->meshlets.bounds[m].cone_axis[2], built.bounds[m].cone_axis[2]);
  }
}

TEST(MeshletFile, RejectsNonZeroPadding) {
  // Three vertices a meshlet: one triangle each, 3 bytes padded to 4.
  const TriangleMesh mesh = testing::TwoTriangles();
  const MeshletResult built = BuildAndCheck(mesh, 3, 124);
  ASSERT_EQ(built.meshlet_triangles.size(), 8u);
  std::string bytes = *EncodeMeshletFile(built, 4, 3, 124);
  ASSERT_TRUE(DecodeMeshletFile(bytes).ok());
  bytes[64 + 16 * 2 + 4 * built.meshlet_vertices.size() + 3] = 1;  // meshlet 0's padding
  absl::StatusOr<MeshletFile> file = DecodeMeshletFile(bytes);
  EXPECT_FALSE(file.ok());
  EXPECT_NE(file.status().message().find("padding"), std::string::npos) << file.status();
}

TEST(MeshletFile, RejectsDamagedFiles) {
  const TriangleMesh mesh = testing::Grid(5);
  const MeshletResult built = BuildAndCheck(mesh, 16, 16);
  const std::string bytes =
      *EncodeMeshletFile(built, static_cast<uint32_t>(mesh.num_vertices()), 16, 16);
  std::string magic = bytes;
  magic[0] = 'X';
  EXPECT_FALSE(DecodeMeshletFile(magic).ok());
  EXPECT_FALSE(DecodeMeshletFile(bytes.substr(0, bytes.size() - 4)).ok());
  EXPECT_FALSE(DecodeMeshletFile(bytes.substr(0, 10)).ok());
  std::string version = bytes;
  version[8] = 2;
  EXPECT_FALSE(DecodeMeshletFile(version).ok());
  std::string reserved = bytes;
  reserved[50] = 1;
  EXPECT_FALSE(DecodeMeshletFile(reserved).ok());
  // A local index past its meshlet's vertices (the first triangle byte).
  std::string local = bytes;
  local[64 + 16 * built.meshlets.size() + 4 * built.meshlet_vertices.size()] =
      static_cast<char>(200);
  absl::StatusOr<MeshletFile> damaged = DecodeMeshletFile(local);
  EXPECT_FALSE(damaged.ok());
  EXPECT_NE(damaged.status().message().find("meshlet 0"), std::string::npos) << damaged.status();
}

TEST(MeshletGlb, HoldsTheMeshInMeshletOrderAndTheArrays) {
  const TriangleMesh mesh = testing::Grid(10, {7});
  const MeshletResult built = BuildAndCheck(mesh, 16, 20);
  absl::StatusOr<std::string> glb = EncodeMeshletGlb(mesh, built, 16, 20);
  ASSERT_TRUE(glb.ok()) << glb.status();
  auto u32 = [&](size_t at) {
    uint32_t v = 0;
    std::memcpy(&v, glb->data() + at, 4);
    return v;
  };
  ASSERT_EQ(glb->substr(0, 4), "glTF");
  EXPECT_EQ(u32(4), 2u);
  EXPECT_EQ(u32(8), glb->size());
  const uint32_t json_bytes = u32(12);
  EXPECT_EQ(glb->substr(16, 4), "JSON");
  const nlohmann::json gltf = nlohmann::json::parse(glb->substr(20, json_bytes));
  const size_t binary = 20 + json_bytes + 8;
  EXPECT_EQ(glb->substr(20 + json_bytes + 4, 4), std::string("BIN\0", 4));
  const nlohmann::json& extras = gltf["meshes"][0]["extras"]["mlclust_meshlets"];
  EXPECT_EQ(extras["meshlet_count"], built.meshlets.size());
  EXPECT_EQ(extras["max_vertices"], 16);
  auto view_bytes = [&](const nlohmann::json& view_number) {
    const nlohmann::json& view = gltf["bufferViews"][view_number.get<size_t>()];
    return glb->substr(binary + view["byteOffset"].get<size_t>(), view["byteLength"].get<size_t>());
  };
  const std::string triangles = view_bytes(extras["meshlet_triangles"]);
  EXPECT_EQ(triangles, std::string(built.meshlet_triangles.begin(), built.meshlet_triangles.end()));
  EXPECT_EQ(view_bytes(extras["bounds"]).size(), 48 * built.meshlets.size());
  // The index buffer: the meshlets' triangles in order, as input vertex indices.
  const nlohmann::json& indices = gltf["accessors"][1];
  EXPECT_EQ(indices["count"], mesh.indices.size());
  const std::string index_bytes = view_bytes(indices["bufferView"]);
  for (size_t t = 0; t < built.triangle_faces.size(); ++t) {
    for (int corner = 0; corner < 3; ++corner) {
      uint32_t index = 0;
      std::memcpy(&index, index_bytes.data() + 4 * (3 * t + corner), 4);
      EXPECT_EQ(index, mesh.indices[3 * built.triangle_faces[t] + corner]);
    }
  }
  // A glTF reader (Assimp, through ReadMeshFile) sees the mesh.
  const std::string path = ::testing::TempDir() + "/meshlets_test.glb";
  ASSERT_TRUE(WriteMeshletGlb(path, mesh, built, 16, 20).ok());
  absl::StatusOr<TriangleMesh> read = ReadMeshFile(path);
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->num_faces(), mesh.num_faces());
}

}  // namespace
}  // namespace mlclust
