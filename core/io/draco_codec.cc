#include "core/io/draco_codec.h"

#include <cmath>
#include <cstdint>
#include <memory>
#include <new>

#include "absl/strings/str_cat.h"
#include "draco/attributes/geometry_attribute.h"
#include "draco/attributes/point_attribute.h"
#include "draco/compression/config/compression_shared.h"
#include "draco/compression/decode.h"
#include "draco/compression/expert_encode.h"
#include "draco/core/decoder_buffer.h"
#include "draco/core/encoder_buffer.h"
#include "draco/mesh/mesh.h"

namespace mlclust {
namespace {

// Draco quantizes to at most 30 bits (its integer coders work on 32-bit values with
// headroom); more is refused by the encoder, so we refuse it first with a clear message.
constexpr int kMaxQuantizationBits = 30;

absl::Status CheckOptions(const DracoEncodeOptions& options) {
  if (options.position_quantization_bits < 0 ||
      options.position_quantization_bits > kMaxQuantizationBits) {
    return absl::InvalidArgumentError(
        absl::StrCat("position_quantization_bits must be 0 (lossless) or 1..", kMaxQuantizationBits,
                     ", got ", options.position_quantization_bits));
  }
  if (options.speed < 0 || options.speed > 10) {
    return absl::InvalidArgumentError(absl::StrCat("speed must be 0..10, got ", options.speed));
  }
  return absl::OkStatus();
}

absl::Status CheckIndices(const TriangleMesh& mesh) {
  if (mesh.positions.size() % 3 != 0 || mesh.indices.size() % 3 != 0) {
    return absl::InvalidArgumentError(absl::StrCat("positions (", mesh.positions.size(),
                                                   " floats) and indices (", mesh.indices.size(),
                                                   " entries) must both hold whole triples"));
  }
  if (mesh.num_vertices() > kMaxMeshElements || mesh.num_faces() > kMaxMeshElements) {
    return absl::InvalidArgumentError(absl::StrCat("mesh too large: ", mesh.num_vertices(),
                                                   " vertices, ", mesh.num_faces(),
                                                   " faces (limit ", kMaxMeshElements, ")"));
  }
  if (absl::Status indices = CheckVertexIndices(mesh); !indices.ok()) return indices;
  return absl::OkStatus();
}

}  // namespace

absl::StatusOr<std::string> EncodeMeshToDraco(const TriangleMesh& mesh,
                                              const DracoEncodeOptions& options) {
  if (absl::Status status = CheckOptions(options); !status.ok()) return status;
  if (absl::Status status = CheckIndices(mesh); !status.ok()) return status;
  if (mesh.num_faces() == 0 && mesh.num_vertices() > 0) {
    // Draco 1.5.5 encodes this but its decoder then refuses the bytes ("Failed to decode
    // geometry data"); fail here, where the caller can still see why.
    return absl::InvalidArgumentError(
        "a mesh with vertices but no faces cannot be sent as a Draco mesh");
  }
  if (options.position_quantization_bits > 0) {
    // Quantizing a NaN or an infinity sends Draco's entropy coder out of bounds (a
    // crash in 1.5.5). Lossless encoding carries them through, so that ValidateMesh on
    // the other side can name the vertex.
    for (size_t i = 0; i < mesh.positions.size(); ++i) {
      if (!std::isfinite(mesh.positions[i])) {
        return absl::InvalidArgumentError(absl::StrCat(
            "vertex ", i / 3, " has a non-finite coordinate, which cannot be quantized"));
      }
    }
  }

  // One point per vertex with an identity point-to-value mapping: point ids on the
  // wire are our vertex ids, so the decoder can hand faces back unchanged.
  const uint32_t num_vertices = static_cast<uint32_t>(mesh.num_vertices());
  draco::Mesh draco_mesh;
  draco_mesh.set_num_points(num_vertices);
  draco::GeometryAttribute position;
  position.Init(draco::GeometryAttribute::POSITION, nullptr, 3, draco::DT_FLOAT32,
                /*normalized=*/false, sizeof(float) * 3, 0);
  const int position_id =
      draco_mesh.AddAttribute(position, /*identity_mapping=*/true, num_vertices);
  draco::PointAttribute* attribute = draco_mesh.attribute(position_id);
  for (uint32_t v = 0; v < num_vertices; ++v) {
    attribute->SetAttributeValue(draco::AttributeValueIndex(v), &mesh.positions[3 * v]);
  }
  draco_mesh.SetNumFaces(mesh.num_faces());
  for (uint32_t f = 0; f < mesh.num_faces(); ++f) {
    draco::Mesh::Face face;
    for (int c = 0; c < 3; ++c) face[c] = draco::PointIndex(mesh.indices[3 * f + c]);
    draco_mesh.SetFace(draco::FaceIndex(f), face);
  }

  draco::ExpertEncoder encoder(draco_mesh);
  // Sequential keeps face and point order (edgebreaker would reorder both and drop
  // degenerate faces, which must reach ValidateMesh so that it can name them).
  encoder.SetEncodingMethod(draco::MESH_SEQUENTIAL_ENCODING);
  encoder.SetSpeedOptions(options.speed, options.speed);
  // The speed options alone leave sequential connectivity as raw 8/16/32-bit indices
  // (half of a lossless fandisk). Delta plus entropy coding of the indices shrinks it
  // several-fold for well under a millisecond per 10k faces; speed 10 keeps it raw.
  encoder.options().SetGlobalBool("compress_connectivity", options.speed < 10);
  if (options.position_quantization_bits > 0) {
    encoder.SetAttributeQuantization(position_id, options.position_quantization_bits);
  }
  draco::EncoderBuffer buffer;
  const draco::Status status = encoder.EncodeToBuffer(&buffer);
  if (!status.ok()) {
    return absl::InternalError(
        absl::StrCat("Draco failed to encode the mesh: ", status.error_msg_string()));
  }
  return std::string(buffer.data(), buffer.size());
}

absl::StatusOr<TriangleMesh> DecodeDracoMesh(std::string_view bytes) {
  if (bytes.empty()) return absl::InvalidArgumentError("Draco data is empty");
  draco::DecoderBuffer buffer;
  buffer.Init(bytes.data(), bytes.size());
  // Reading the header first lets us refuse a point cloud with a message that says so,
  // instead of Draco's generic "Not a Draco mesh" from DecodeMeshFromBuffer.
  // GetEncodedGeometryType works on a copy of the buffer and does not consume it.
  const auto geometry_type = draco::Decoder::GetEncodedGeometryType(&buffer);
  if (!geometry_type.ok()) {
    return absl::InvalidArgumentError(
        absl::StrCat("not Draco data: ", geometry_type.status().error_msg_string()));
  }
  if (geometry_type.value() == draco::POINT_CLOUD) {
    return absl::InvalidArgumentError(
        "Draco data holds a point cloud, but a triangle mesh is required");
  }
  if (geometry_type.value() != draco::TRIANGULAR_MESH) {
    return absl::InvalidArgumentError(
        absl::StrCat("Draco data holds geometry of unknown type ", geometry_type.value()));
  }

  std::unique_ptr<draco::Mesh> decoded;
  // A hostile header can announce billions of elements; Draco allocates before it finds
  // the data missing. Failing the allocation must not take the server down.
  try {
    draco::Decoder decoder;
    auto result = decoder.DecodeMeshFromBuffer(&buffer);
    if (!result.ok()) {
      return absl::InvalidArgumentError(
          absl::StrCat("invalid Draco mesh: ", result.status().error_msg_string()));
    }
    decoded = std::move(result).value();
  } catch (const std::bad_alloc&) {
    return absl::InvalidArgumentError(
        "invalid Draco mesh: its header asks for more memory than is available");
  }

  const draco::PointAttribute* position =
      decoded->GetNamedAttribute(draco::GeometryAttribute::POSITION);
  if (position == nullptr) {
    return absl::InvalidArgumentError("Draco mesh has no POSITION attribute");
  }
  if (position->num_components() != 3) {
    return absl::InvalidArgumentError(absl::StrCat("Draco POSITION attribute has ",
                                                   position->num_components(),
                                                   " components; 3 are required"));
  }
  const size_t num_points = decoded->num_points();
  const size_t num_faces = decoded->num_faces();
  if (num_points > kMaxMeshElements || num_faces > kMaxMeshElements) {
    return absl::InvalidArgumentError(absl::StrCat("Draco mesh too large: ", num_points,
                                                   " points, ", num_faces, " faces (limit ",
                                                   kMaxMeshElements, ")"));
  }

  if (!position->is_mapping_identity() && position->indices_map_size() < num_points) {
    return absl::InvalidArgumentError(absl::StrCat(
        "Draco mesh: POSITION maps ", position->indices_map_size(), " of ", num_points, " points"));
  }

  TriangleMesh mesh;
  mesh.positions.resize(3 * num_points);
  const size_t num_values = position->size();
  for (uint32_t p = 0; p < num_points; ++p) {
    // Points map to attribute values; with several attributes Draco may share one
    // position value between points, so the mapping is followed, not assumed.
    const draco::AttributeValueIndex value = position->mapped_index(draco::PointIndex(p));
    if (value.value() >= num_values ||
        !position->ConvertValue<float>(value, 3, &mesh.positions[3 * size_t{p}])) {
      return absl::InvalidArgumentError(
          absl::StrCat("Draco mesh: point ", p, " has no readable position"));
    }
  }
  mesh.indices.resize(3 * num_faces);
  for (uint32_t f = 0; f < num_faces; ++f) {
    const draco::Mesh::Face& face = decoded->face(draco::FaceIndex(f));
    for (int c = 0; c < 3; ++c) {
      const uint32_t point = face[c].value();
      if (point >= num_points) {
        return absl::InvalidArgumentError(
            absl::StrCat("Draco mesh: face ", f, " corner ", c, " refers to point ", point,
                         ", but the mesh has ", num_points, " points"));
      }
      mesh.indices[3 * size_t{f} + c] = point;
    }
  }
  return mesh;
}

}  // namespace mlclust
