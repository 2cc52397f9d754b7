#include "core/meshlets/meshlet_gltf.h"

#include <algorithm>
#include <cstring>
#include <fstream>
#include <limits>

#include "absl/strings/str_cat.h"
#include "core/meshlets/meshlet_file.h"
#include "nlohmann/json.hpp"

namespace mlclust {
namespace {

using Json = nlohmann::json;

constexpr uint32_t kGlbMagic = 0x46546C67;     // "glTF"
constexpr uint32_t kJsonChunk = 0x4E4F534A;    // "JSON"
constexpr uint32_t kBinaryChunk = 0x004E4942;  // "BIN\0"
constexpr int kUnsignedInt = 5125;             // glTF componentType
constexpr int kFloat = 5126;
constexpr int kArrayBuffer = 34962;  // bufferView targets
constexpr int kElementArrayBuffer = 34963;

void PutU32(std::string& out, uint32_t value) {
  char bytes[4];
  std::memcpy(bytes, &value, 4);
  out.append(bytes, 4);
}

// Appends `bytes` to the binary chunk as a new view (padded to 4 bytes); returns its number.
size_t AddView(std::string& binary, Json& views, const void* data, size_t size, int target = 0) {
  Json view = {{"buffer", 0}, {"byteOffset", binary.size()}, {"byteLength", size}};
  if (target != 0) view["target"] = target;
  binary.append(static_cast<const char*>(data), size);
  binary.resize((binary.size() + 3) & ~size_t{3}, '\0');
  views.push_back(view);
  return views.size() - 1;
}

}  // namespace

absl::StatusOr<std::string> EncodeMeshletGlb(const TriangleMesh& mesh,
                                             const MeshletResult& meshlets, uint32_t max_vertices,
                                             uint32_t max_triangles) {
  if (meshlets.triangle_faces.size() != mesh.num_faces()) {
    return absl::InvalidArgumentError(absl::StrCat("meshlet glTF: ", meshlets.triangle_faces.size(),
                                                   " meshlet triangles for ", mesh.num_faces(),
                                                   " faces"));
  }
  std::string binary;
  Json views = Json::array();
  const size_t positions = AddView(binary, views, mesh.positions.data(),
                                   mesh.positions.size() * sizeof(float), kArrayBuffer);
  std::vector<uint32_t> indices;
  indices.reserve(mesh.indices.size());
  for (const uint32_t face : meshlets.triangle_faces) {
    for (int corner = 0; corner < 3; ++corner)
      indices.push_back(mesh.indices[3 * size_t{face} + corner]);
  }
  const size_t index_view = AddView(binary, views, indices.data(),
                                    indices.size() * sizeof(uint32_t), kElementArrayBuffer);
  Json extras = {{"version", 1},
                 {"max_vertices", max_vertices},
                 {"max_triangles", max_triangles},
                 {"meshlet_count", meshlets.meshlets.size()}};
  extras["meshlets"] =
      AddView(binary, views, meshlets.meshlets.data(), meshlets.meshlets.size() * sizeof(Meshlet));
  extras["meshlet_vertices"] = AddView(binary, views, meshlets.meshlet_vertices.data(),
                                       meshlets.meshlet_vertices.size() * sizeof(uint32_t));
  extras["meshlet_triangles"] =
      AddView(binary, views, meshlets.meshlet_triangles.data(), meshlets.meshlet_triangles.size());
  extras["triangle_faces"] = AddView(binary, views, meshlets.triangle_faces.data(),
                                     meshlets.triangle_faces.size() * sizeof(uint32_t));
  if (!meshlets.bounds.empty()) {
    const std::string bounds = EncodeMeshletBounds(meshlets.bounds);
    extras["bounds"] = AddView(binary, views, bounds.data(), bounds.size());
  }
  std::array<float, 3> low = {std::numeric_limits<float>::max(), std::numeric_limits<float>::max(),
                              std::numeric_limits<float>::max()};
  std::array<float, 3> high = {-low[0], -low[1], -low[2]};
  for (size_t v = 0; v < mesh.num_vertices(); ++v) {
    for (int axis = 0; axis < 3; ++axis) {
      low[axis] = std::min(low[axis], mesh.positions[3 * v + axis]);
      high[axis] = std::max(high[axis], mesh.positions[3 * v + axis]);
    }
  }
  Json gltf = {
      {"asset", {{"version", "2.0"}, {"generator", "mlclust mesh --meshlets"}}},
      {"scene", 0},
      {"scenes", Json::array({{{"nodes", Json::array({0})}}})},
      {"nodes", Json::array({{{"mesh", 0}}})},
      {"meshes",
       Json::array(
           {{{"primitives",
              Json::array({{{"attributes", {{"POSITION", 0}}}, {"indices", 1}, {"mode", 4}}})},
             {"extras", {{"mlclust_meshlets", extras}}}}})},
      {"accessors", Json::array({{{"bufferView", positions},
                                  {"componentType", kFloat},
                                  {"count", mesh.num_vertices()},
                                  {"type", "VEC3"},
                                  {"min", low},
                                  {"max", high}},
                                 {{"bufferView", index_view},
                                  {"componentType", kUnsignedInt},
                                  {"count", indices.size()},
                                  {"type", "SCALAR"}}})},
      {"bufferViews", views},
      {"buffers", Json::array({{{"byteLength", binary.size()}}})}};
  std::string json = gltf.dump();
  json.resize((json.size() + 3) & ~size_t{3}, ' ');
  const uint64_t total = 12 + 8 + json.size() + 8 + binary.size();
  if (total > std::numeric_limits<uint32_t>::max()) {
    return absl::InvalidArgumentError(
        absl::StrCat("meshlet glTF: ", total, " bytes, past the 4 GiB a .glb can hold"));
  }
  std::string out;
  out.reserve(total);
  PutU32(out, kGlbMagic);
  PutU32(out, 2);
  PutU32(out, static_cast<uint32_t>(total));
  PutU32(out, static_cast<uint32_t>(json.size()));
  PutU32(out, kJsonChunk);
  out += json;
  PutU32(out, static_cast<uint32_t>(binary.size()));
  PutU32(out, kBinaryChunk);
  out += binary;
  return out;
}

absl::Status WriteMeshletGlb(const std::string& path, const TriangleMesh& mesh,
                             const MeshletResult& meshlets, uint32_t max_vertices,
                             uint32_t max_triangles) {
  absl::StatusOr<std::string> bytes = EncodeMeshletGlb(mesh, meshlets, max_vertices, max_triangles);
  if (!bytes.ok()) return bytes.status();
  std::ofstream out(path, std::ios::binary);
  out.write(bytes->data(), static_cast<std::streamsize>(bytes->size()));
  out.close();
  if (!out) return absl::UnavailableError(absl::StrCat("cannot write the meshlet glTF ", path));
  return absl::OkStatus();
}

}  // namespace mlclust
