#include "core/io/gltf_draco.h"

#include <cstdint>
#include <cstring>
#include <memory>
#include <new>
#include <vector>

#include "absl/strings/escaping.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "core/base/status_macros.h"
#include "draco/attributes/point_attribute.h"
#include "draco/compression/decode.h"
#include "draco/core/decoder_buffer.h"
#include "draco/mesh/mesh.h"
#include "nlohmann/json.hpp"

namespace mlclust {
namespace {

using Json = nlohmann::json;

constexpr char kExtension[] = "KHR_draco_mesh_compression";
constexpr uint32_t kGlbMagic = 0x46546C67;   // "glTF"
constexpr uint32_t kChunkJson = 0x4E4F534A;  // "JSON"
constexpr uint32_t kChunkBin = 0x004E4942;   // "BIN\0"
// glTF accessor component types (glTF 2.0, 3.6.2.2).
constexpr int kFloat = 5126;
constexpr int kUnsignedInt = 5125;

uint32_t ReadU32(std::string_view bytes, size_t at) {
  uint32_t value = 0;
  for (int i = 3; i >= 0; --i) value = (value << 8) | static_cast<uint8_t>(bytes[at + i]);
  return value;
}

void AppendU32(std::string& out, uint32_t value) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<char>(value >> (8 * i)));
}

bool IsGlb(std::string_view file) { return file.size() >= 12 && ReadU32(file, 0) == kGlbMagic; }

// The JSON text and the BIN chunk of a GLB (glTF 2.0, 4.4), or the whole file as JSON.
struct Container {
  std::string_view json;
  std::string_view bin;
  bool has_bin = false;
};

absl::StatusOr<Container> SplitContainer(std::string_view file) {
  Container container;
  if (!IsGlb(file)) {
    container.json = file;
    return container;
  }
  if (ReadU32(file, 4) != 2) {
    return absl::InvalidArgumentError(
        absl::StrCat("GLB version ", ReadU32(file, 4), "; 2 is read"));
  }
  size_t at = 12;
  bool first = true;
  while (at + 8 <= file.size()) {
    const uint32_t length = ReadU32(file, at), type = ReadU32(file, at + 4);
    if (length > file.size() - at - 8) {
      return absl::InvalidArgumentError(
          absl::StrCat("GLB chunk at byte ", at, " runs past the end of the file"));
    }
    const std::string_view data = file.substr(at + 8, length);
    if (first && type != kChunkJson) {
      return absl::InvalidArgumentError("GLB: the first chunk is not JSON");
    }
    if (first) container.json = data;
    if (!first && type == kChunkBin && !container.has_bin) {
      container.bin = data;
      container.has_bin = true;
    }
    first = false;
    at += 8 + size_t{length};
  }
  if (first) return absl::InvalidArgumentError("GLB without a JSON chunk");
  return container;
}

// The bytes of buffer `index`: the GLB's BIN chunk, a base64 data: URI or a file.
absl::StatusOr<std::string> LoadBuffer(const Json& buffer, size_t index, const Container& container,
                                       const GltfUriReader& read_uri) {
  std::string data;
  if (!buffer.contains("uri")) {
    if (index != 0 || !container.has_bin) {
      return absl::InvalidArgumentError(
          absl::StrCat("buffer ", index, " has no uri and there is no GLB BIN chunk"));
    }
    data = std::string(container.bin);
  } else {
    const std::string uri = buffer.at("uri").get<std::string>();
    if (absl::StartsWith(uri, "data:")) {
      const size_t comma = uri.find(',');
      if (comma == std::string::npos || uri.substr(0, comma).find(";base64") == std::string::npos ||
          !absl::Base64Unescape(absl::string_view(uri).substr(comma + 1), &data)) {
        return absl::InvalidArgumentError(
            absl::StrCat("buffer ", index, ": a data: URI that is not base64"));
      }
    } else {
      // A relative URI, as glTF allows (percent-escapes are not decoded).
      absl::StatusOr<std::string> file = read_uri(uri);
      if (!file.ok()) {
        return absl::InvalidArgumentError(
            absl::StrCat("buffer ", index, " (", uri, "): ", file.status().message()));
      }
      data = *std::move(file);
    }
  }
  const uint64_t length = buffer.at("byteLength").get<uint64_t>();
  if (data.size() < length) {
    return absl::InvalidArgumentError(
        absl::StrCat("buffer ", index, " holds ", data.size(), " bytes, byteLength says ", length));
  }
  return data;
}

void PadTo4(std::string& bytes, char pad) {
  while (bytes.size() % 4 != 0) bytes.push_back(pad);
}

// Decodes one compressed primitive and points its POSITION and indices accessors at the
// decoded data, appended to `bin`.
absl::Status DecodePrimitive(Json& gltf, Json& primitive, const std::vector<std::string>& buffers,
                             std::string& bin) {
  const Json& extension = primitive.at("extensions").at(kExtension);
  const Json& view = gltf.at("bufferViews").at(extension.at("bufferView").get<size_t>());
  const size_t buffer = view.at("buffer").get<size_t>();
  const uint64_t offset = view.value("byteOffset", uint64_t{0});
  const uint64_t length = view.at("byteLength").get<uint64_t>();
  if (buffer >= buffers.size() || offset > buffers[buffer].size() ||
      length > buffers[buffer].size() - offset) {
    return absl::InvalidArgumentError("its Draco bufferView lies outside its buffer");
  }
  draco::DecoderBuffer input;
  input.Init(buffers[buffer].data() + offset, length);
  std::unique_ptr<draco::Mesh> mesh;
  try {
    draco::Decoder decoder;
    auto decoded = decoder.DecodeMeshFromBuffer(&input);
    if (!decoded.ok()) {
      return absl::InvalidArgumentError(
          absl::StrCat("invalid Draco data: ", decoded.status().error_msg_string()));
    }
    mesh = std::move(decoded).value();
  } catch (const std::bad_alloc&) {
    return absl::InvalidArgumentError("invalid Draco data: it asks for more memory than there is");
  }

  // The extension maps glTF attribute names to Draco unique ids; only POSITION is kept.
  const draco::PointAttribute* position =
      mesh->GetAttributeByUniqueId(extension.at("attributes").at("POSITION").get<uint32_t>());
  if (position == nullptr || position->num_components() != 3) {
    return absl::InvalidArgumentError("its Draco data has no 3-component POSITION attribute");
  }
  const uint32_t num_points = mesh->num_points();
  const uint32_t num_faces = mesh->num_faces();
  Json& accessors = gltf.at("accessors");
  const size_t position_accessor = primitive.at("attributes").at("POSITION").get<size_t>();
  if (accessors.at(position_accessor).at("count").get<uint64_t>() != num_points) {
    return absl::InvalidArgumentError(absl::StrCat(
        "its POSITION accessor counts ", accessors.at(position_accessor).at("count").dump(),
        " vertices, its Draco data ", num_points));
  }

  Json& views = gltf.at("bufferViews");
  auto add_view = [&](const std::string& data) {
    PadTo4(bin, '\0');
    views.push_back({{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", data.size()}});
    bin += data;
    return views.size() - 1;
  };

  std::string positions(size_t{num_points} * 12, '\0');
  for (uint32_t p = 0; p < num_points; ++p) {
    float xyz[3];
    const draco::AttributeValueIndex value = position->mapped_index(draco::PointIndex(p));
    if (value.value() >= position->size() || !position->ConvertValue<float>(value, 3, xyz)) {
      return absl::InvalidArgumentError(absl::StrCat("Draco point ", p, " has no position"));
    }
    std::memcpy(&positions[size_t{p} * 12], xyz, 12);
  }
  std::string indices;
  indices.reserve(size_t{num_faces} * 12);
  for (uint32_t f = 0; f < num_faces; ++f) {
    for (int c = 0; c < 3; ++c) AppendU32(indices, mesh->face(draco::FaceIndex(f))[c].value());
  }

  Json& position_json = accessors.at(position_accessor);
  position_json["bufferView"] = add_view(positions);
  position_json["byteOffset"] = 0;
  position_json["componentType"] = kFloat;
  position_json.erase("sparse");
  position_json.erase("normalized");
  Json indices_json = {{"bufferView", add_view(indices)},
                       {"byteOffset", 0},
                       {"componentType", kUnsignedInt},
                       {"count", size_t{num_faces} * 3},
                       {"type", "SCALAR"}};
  if (primitive.contains("indices")) {
    const size_t index_accessor = primitive.at("indices").get<size_t>();
    if (accessors.at(index_accessor).at("count").get<uint64_t>() != size_t{num_faces} * 3) {
      return absl::InvalidArgumentError(absl::StrCat(
          "its indices accessor counts ", accessors.at(index_accessor).at("count").dump(),
          " indices, its Draco data ", num_faces, " triangles"));
    }
  }
  // A new accessor, so that an accessor another primitive shares is left alone.
  accessors.push_back(indices_json);
  primitive["indices"] = accessors.size() - 1;
  primitive["attributes"] = Json{{"POSITION", position_accessor}};
  primitive.erase("targets");  // Morph targets are not read, and may be compressed too.
  primitive["extensions"].erase(kExtension);
  if (primitive["extensions"].empty()) primitive.erase("extensions");
  return absl::OkStatus();
}

void RemoveFromList(Json& gltf, const char* list) {
  if (!gltf.contains(list)) return;
  Json kept = Json::array();
  for (const Json& name : gltf[list]) {
    if (name != kExtension) kept.push_back(name);
  }
  if (kept.empty()) {
    gltf.erase(list);
  } else {
    gltf[list] = kept;
  }
}

}  // namespace

absl::StatusOr<std::string> PackGlb(std::string json, std::string bin) {
  PadTo4(json, ' ');
  PadTo4(bin, '\0');
  if (12 + 8 + json.size() + 8 + bin.size() > uint64_t{0xFFFFFFFF}) {
    return absl::InvalidArgumentError("the glTF is over 4 GiB, GLB's limit");
  }
  std::string glb;
  glb.reserve(28 + json.size() + bin.size());
  AppendU32(glb, kGlbMagic);
  AppendU32(glb, 2);
  AppendU32(glb, static_cast<uint32_t>(28 + json.size() + bin.size()));
  AppendU32(glb, static_cast<uint32_t>(json.size()));
  AppendU32(glb, kChunkJson);
  glb += json;
  AppendU32(glb, static_cast<uint32_t>(bin.size()));
  AppendU32(glb, kChunkBin);
  glb += bin;
  return glb;
}

bool GltfUsesDraco(std::string_view file) {
  absl::StatusOr<Container> container = SplitContainer(file);
  return container.ok() && container->json.find(kExtension) != std::string_view::npos;
}

absl::StatusOr<std::string> DecompressDracoGltf(std::string_view file,
                                                const GltfUriReader& read_uri) {
  MLCLUST_ASSIGN_OR_RETURN(Container container, SplitContainer(file));
  Json gltf = Json::parse(container.json, nullptr, /*allow_exceptions=*/false);
  if (gltf.is_discarded() || !gltf.is_object()) {
    return absl::InvalidArgumentError("the glTF JSON does not parse");
  }
  try {
    // All buffers become one: the old ones, 4-byte aligned, then the decoded data.
    std::vector<std::string> buffers;
    std::vector<uint64_t> base;
    std::string bin;
    if (gltf.contains("buffers")) {
      for (size_t b = 0; b < gltf["buffers"].size(); ++b) {
        MLCLUST_ASSIGN_OR_RETURN(std::string data,
                                 LoadBuffer(gltf["buffers"][b], b, container, read_uri));
        PadTo4(bin, '\0');
        base.push_back(bin.size());
        bin += data;
        buffers.push_back(std::move(data));
      }
    }
    if (gltf.contains("bufferViews")) {
      for (Json& view : gltf["bufferViews"]) {
        const size_t buffer = view.at("buffer").get<size_t>();
        if (buffer >= base.size()) {
          return absl::InvalidArgumentError(
              absl::StrCat("a bufferView names buffer ", buffer, " of ", base.size()));
        }
        view["buffer"] = 0;
        view["byteOffset"] = base[buffer] + view.value("byteOffset", uint64_t{0});
      }
    } else {
      gltf["bufferViews"] = Json::array();
    }
    if (!gltf.contains("accessors")) gltf["accessors"] = Json::array();
    if (gltf.contains("meshes")) {
      for (size_t m = 0; m < gltf["meshes"].size(); ++m) {
        Json& primitives = gltf["meshes"][m]["primitives"];
        for (size_t p = 0; p < primitives.size(); ++p) {
          Json& primitive = primitives[p];
          if (!primitive.contains("extensions") || !primitive["extensions"].contains(kExtension)) {
            continue;
          }
          if (absl::Status status = DecodePrimitive(gltf, primitive, buffers, bin); !status.ok()) {
            return absl::InvalidArgumentError(absl::StrCat("mesh ", m, " primitive ", p, " (",
                                                           kExtension, "): ", status.message()));
          }
        }
      }
    }
    RemoveFromList(gltf, "extensionsUsed");
    RemoveFromList(gltf, "extensionsRequired");
    gltf["buffers"] = Json::array({Json{{"byteLength", bin.size()}}});
    PadTo4(bin, '\0');

    return PackGlb(gltf.dump(), std::move(bin));
  } catch (const Json::exception& e) {
    // A member missing or of the wrong type, wherever it is.
    return absl::InvalidArgumentError(absl::StrCat("glTF JSON: ", e.what()));
  }
}

}  // namespace mlclust
