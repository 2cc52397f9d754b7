// Writes the binary seeds of the fuzz corpora (corpus/<target>/): Draco payloads, Draco
// glTF files, point batches and job requests, made with the library's own encoder so that
// they are what real clients send. The text seeds (OFF, PLY, CSV, .npy) are kept as files.
// Run once after changing a format: make_seed_corpus fuzz/corpus
#include <bit>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "absl/strings/escaping.h"
#include "absl/strings/str_cat.h"
#include "core/io/draco_codec.h"
#include "core/io/gltf_draco.h"
#include "mlclust/v1/mlclust.pb.h"

namespace mlclust {
namespace {

void AppendLe32(std::string& out, uint32_t value) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<char>(value >> (8 * i)));
}

void Write(const std::filesystem::path& path, const std::string& bytes) {
  std::filesystem::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
}

TriangleMesh Tetrahedron() {
  return {{0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1}, {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3}};
}

// An n x n grid of unit squares, two triangles each.
TriangleMesh Grid(uint32_t n) {
  TriangleMesh mesh;
  for (uint32_t y = 0; y <= n; ++y) {
    for (uint32_t x = 0; x <= n; ++x) {
      mesh.positions.insert(mesh.positions.end(), {float(x), float(y), 0.f});
    }
  }
  for (uint32_t y = 0; y < n; ++y) {
    for (uint32_t x = 0; x < n; ++x) {
      const uint32_t v = y * (n + 1) + x;
      mesh.indices.insert(mesh.indices.end(), {v, v + 1, v + n + 2, v, v + n + 2, v + n + 1});
    }
  }
  return mesh;
}

std::string Encode(const TriangleMesh& mesh, const DracoEncodeOptions& options) {
  absl::StatusOr<std::string> bytes = EncodeMeshToDraco(mesh, options);
  if (!bytes.ok()) {
    std::fprintf(stderr, "%s\n", bytes.status().ToString().c_str());
    std::exit(1);
  }
  return *bytes;
}

// The glTF JSON of one mesh whose one primitive is Draco data in bufferView 0.
std::string DracoGltfJson(size_t draco_bytes, size_t num_vertices, size_t num_faces,
                          const std::string& buffer_json) {
  return absl::StrCat(
      R"({"asset":{"version":"2.0"},"extensionsUsed":["KHR_draco_mesh_compression"],)",
      R"("scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0,"translation":[1,0,0]}],)",
      R"("meshes":[{"primitives":[{"attributes":{"POSITION":0},"indices":1,"mode":4,)",
      R"("extensions":{"KHR_draco_mesh_compression":{"bufferView":0,"attributes":{"POSITION":0}}}}]}],)",
      R"("accessors":[{"componentType":5126,"count":)", num_vertices,
      R"(,"type":"VEC3","min":[0,0,0],"max":[1,1,1]},{"componentType":5125,"count":)",
      3 * num_faces, R"(,"type":"SCALAR"}],"bufferViews":[{"buffer":0,"byteOffset":0,)",
      R"("byteLength":)", draco_bytes, R"(}],"buffers":[)", buffer_json, "]}");
}

std::string Request(const v1::JobSpec& spec, const std::string& input) {
  const std::string bytes = spec.SerializeAsString();
  std::string out;
  out.push_back(static_cast<char>(bytes.size() & 0xff));
  out.push_back(static_cast<char>(bytes.size() >> 8));
  return out + bytes + input;
}

int Main(const std::filesystem::path& corpus) {
  const TriangleMesh tetrahedron = Tetrahedron();
  const TriangleMesh grid = Grid(3);
  DracoEncodeOptions sequential;
  DracoEncodeOptions fast;
  fast.speed = 10;
  DracoEncodeOptions edgebreaker;
  edgebreaker.method = DracoMethod::kEdgebreaker;
  edgebreaker.position_quantization_bits = 11;
  edgebreaker.write_face_ids = true;
  const std::string tet_draco = Encode(tetrahedron, sequential);
  const std::string grid_draco = Encode(grid, edgebreaker);
  Write(corpus / "draco/tetrahedron_sequential.drc", tet_draco);
  Write(corpus / "draco/grid_sequential_speed10.drc", Encode(grid, fast));
  Write(corpus / "draco/grid_edgebreaker_face_ids.drc", grid_draco);
  edgebreaker.write_face_ids = false;
  Write(corpus / "draco/grid_edgebreaker.drc", Encode(grid, edgebreaker));

  // Draco glTF: a GLB with the data in its BIN chunk, a .gltf with a data: URI, and a
  // .gltf whose buffer is the file "buffer.bin" (the fuzz target's reader serves the
  // input's last 256 bytes under that name, so the Draco bytes end the seed).
  Write(corpus / "gltf_draco/tetrahedron.glb",
        *PackGlb(DracoGltfJson(tet_draco.size(), 4, 4,
                               absl::StrCat(R"({"byteLength":)", tet_draco.size(), "}")),
                 tet_draco));
  Write(corpus / "gltf_draco/grid_data_uri.gltf",
        DracoGltfJson(grid_draco.size(), grid.num_vertices(), grid.num_faces(),
                      absl::StrCat(R"({"byteLength":)", grid_draco.size(),
                                   R"(,"uri":"data:application/octet-stream;base64,)",
                                   absl::Base64Escape(grid_draco), R"("})")));
  std::string external =
      DracoGltfJson(tet_draco.size(), 4, 4,
                    absl::StrCat(R"({"byteLength":)", tet_draco.size(), R"(,"uri":"buffer.bin"})"));
  external.append(256 - tet_draco.size(), ' ');
  Write(corpus / "gltf_draco/tetrahedron_buffer_file.gltf", external + tet_draco);

  // Point batches: d, grid, then the float32 values.
  auto batch = [](uint8_t d, uint8_t grid_cells, const std::vector<float>& values) {
    std::string out{static_cast<char>(d), static_cast<char>(grid_cells)};
    for (float v : values) AppendLe32(out, std::bit_cast<uint32_t>(v));
    return out;
  };
  Write(corpus / "points_batch/2d_six_points.bin",
        batch(2, 0, {0, 0, 1, 0, 0, 1, 5, 5, 6, 5, 5, 6}));
  Write(corpus / "points_batch/3d_grid4.bin",
        batch(3, 4, {0, 0, 0, 1, 1, 1, 0.5f, 0.25f, 0, -3, 2, 1e6f, 1e-30f, 0, 7}));
  Write(corpus / "points_batch/1d_equal.bin", batch(1, 0, {2, 2, 2, 2}));

  // Requests: a mesh job and a points job with options.
  v1::JobSpec mesh_spec;
  mesh_spec.set_input_kind(v1::INPUT_KIND_DRACO_MESH);
  mesh_spec.set_input_bytes(tet_draco.size());
  mesh_spec.set_algorithm(v1::ALGORITHM_ML);
  mesh_spec.set_energy(v1::ENERGY_CVD_ADAPTIVE);
  (*mesh_spec.mutable_options())["gamma"] = "1.5";
  (*mesh_spec.mutable_options())["density"] = "power";
  Write(corpus / "request/mesh_ml.bin", Request(mesh_spec, tet_draco));
  mesh_spec.set_algorithm(v1::ALGORITHM_BB);
  mesh_spec.set_energy(v1::ENERGY_PLANAR);
  mesh_spec.set_clusters(2);
  mesh_spec.clear_options();
  (*mesh_spec.mutable_options())["init"] = "random";
  (*mesh_spec.mutable_options())["max-iterations"] = "5";
  Write(corpus / "request/mesh_bb.bin", Request(mesh_spec, tet_draco));
  v1::JobSpec points_spec;
  points_spec.set_input_kind(v1::INPUT_KIND_POINTS_F32);
  points_spec.set_point_dims(2);
  points_spec.set_algorithm(v1::ALGORITHM_LN_KMEANS);
  points_spec.set_clusters(2);
  (*points_spec.mutable_options())["init"] = "kmeans++";
  const std::string points = batch(2, 0, {0, 0, 1, 0, 0, 1, 5, 5}).substr(2);
  points_spec.set_input_bytes(points.size());
  Write(corpus / "request/points_ln_kmeans.bin", Request(points_spec, points));
  points_spec.set_algorithm(v1::ALGORITHM_PML);
  points_spec.clear_options();
  (*points_spec.mutable_options())["pml-until"] = "2";
  (*points_spec.mutable_options())["grid"] = "4";
  Write(corpus / "request/points_pml.bin", Request(points_spec, points));
  return 0;
}

}  // namespace
}  // namespace mlclust

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s CORPUS_DIR\n", argv[0]);
    return 2;
  }
  return mlclust::Main(argv[1]);
}
