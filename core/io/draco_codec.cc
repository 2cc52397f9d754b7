#include "core/io/draco_codec.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <new>

#include "absl/strings/str_cat.h"
#include "core/base/status_macros.h"
#include "core/io/allocation_budget.h"
#include "draco/attributes/geometry_attribute.h"
#include "draco/attributes/point_attribute.h"
#include "draco/compression/config/compression_shared.h"
#include "draco/compression/decode.h"
#include "draco/compression/expert_encode.h"
#include "draco/core/decoder_buffer.h"
#include "draco/core/encoder_buffer.h"
#include "draco/core/varint_decoding.h"
#include "draco/mesh/mesh.h"
#include "draco/metadata/geometry_metadata.h"
#include "draco/metadata/metadata_decoder.h"

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
  if (options.write_face_ids && options.method == DracoMethod::kSequential) {
    return absl::InvalidArgumentError(
        "write_face_ids needs the edgebreaker method (sequential keeps the face order, and "
        "its per-corner points would lose which corners share a vertex)");
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
  MLCLUST_RETURN_IF_ERROR(CheckVertexIndices(mesh));
  return absl::OkStatus();
}

// The face id attribute: one component of an integer type, so that ids are exact.
absl::Status CheckFaceIdAttribute(const draco::PointAttribute& ids, size_t num_points) {
  const draco::DataType type = ids.data_type();
  const bool integer = type == draco::DT_UINT8 || type == draco::DT_UINT16 ||
                       type == draco::DT_UINT32 || type == draco::DT_INT8 ||
                       type == draco::DT_INT16 || type == draco::DT_INT32;
  if (ids.num_components() != 1 || !integer) {
    return absl::InvalidArgumentError(absl::StrCat(
        "Draco mesh: the '", kDracoFaceIdAttributeName,
        "' attribute must have 1 integer component, got ", static_cast<int>(ids.num_components()),
        " of Draco data type ", static_cast<int>(type)));
  }
  if (!ids.is_mapping_identity() && ids.indices_map_size() < num_points) {
    return absl::InvalidArgumentError(absl::StrCat("Draco mesh: '", kDracoFaceIdAttributeName,
                                                   "' maps ", ids.indices_map_size(), " of ",
                                                   num_points, " points"));
  }
  return absl::OkStatus();
}

}  // namespace

absl::StatusOr<std::string> EncodeMeshToDraco(const TriangleMesh& mesh,
                                              const DracoEncodeOptions& options) {
  MLCLUST_RETURN_IF_ERROR(CheckOptions(options));
  MLCLUST_RETURN_IF_ERROR(CheckIndices(mesh));
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

  const uint32_t num_vertices = static_cast<uint32_t>(mesh.num_vertices());
  const uint32_t num_faces = static_cast<uint32_t>(mesh.num_faces());
  draco::Mesh draco_mesh;
  draco::GeometryAttribute position;
  position.Init(draco::GeometryAttribute::POSITION, nullptr, 3, draco::DT_FLOAT32,
                /*normalized=*/false, sizeof(float) * 3, 0);
  int position_id = -1;
  draco_mesh.SetNumFaces(num_faces);
  if (!options.write_face_ids) {
    // One point per vertex with an identity point-to-value mapping: point ids on the
    // wire are our vertex ids, so the decoder can hand faces back unchanged.
    draco_mesh.set_num_points(num_vertices);
    position_id = draco_mesh.AddAttribute(position, /*identity_mapping=*/true, num_vertices);
    for (uint32_t f = 0; f < num_faces; ++f) {
      draco::Mesh::Face face;
      for (int c = 0; c < 3; ++c) face[c] = draco::PointIndex(mesh.indices[3 * f + c]);
      draco_mesh.SetFace(draco::FaceIndex(f), face);
    }
  } else {
    // A point per corner: position value = our vertex (edgebreaker builds its
    // connectivity from position values, so corners of one vertex stay one vertex), face
    // id value = the face. Every edge is a seam of the id attribute, which Draco codes
    // as a face attribute.
    draco_mesh.set_num_points(3 * num_faces);
    position_id = draco_mesh.AddAttribute(position, /*identity_mapping=*/false, num_vertices);
    draco::GeometryAttribute face_id;
    face_id.Init(draco::GeometryAttribute::GENERIC, nullptr, 1, draco::DT_UINT32,
                 /*normalized=*/false, sizeof(uint32_t), 0);
    const int face_id_id = draco_mesh.AddAttribute(face_id, /*identity_mapping=*/false, num_faces);
    draco::PointAttribute* ids = draco_mesh.attribute(face_id_id);
    draco::PointAttribute* positions = draco_mesh.attribute(position_id);
    ids->SetExplicitMapping(3 * num_faces);
    positions->SetExplicitMapping(3 * num_faces);
    for (uint32_t f = 0; f < num_faces; ++f) {
      ids->SetAttributeValue(draco::AttributeValueIndex(f), &f);
      draco::Mesh::Face face;
      for (int c = 0; c < 3; ++c) {
        const draco::PointIndex point(3 * f + c);
        face[c] = point;
        positions->SetPointMapEntry(point, draco::AttributeValueIndex(mesh.indices[3 * f + c]));
        ids->SetPointMapEntry(point, draco::AttributeValueIndex(f));
      }
      draco_mesh.SetFace(draco::FaceIndex(f), face);
    }
    draco_mesh.SetAttributeElementType(face_id_id, draco::MESH_FACE_ATTRIBUTE);
    auto metadata = std::make_unique<draco::AttributeMetadata>();
    metadata->AddEntryString("name", kDracoFaceIdAttributeName);
    draco_mesh.AddAttributeMetadata(face_id_id, std::move(metadata));
  }
  draco::PointAttribute* attribute = draco_mesh.attribute(position_id);
  for (uint32_t v = 0; v < num_vertices; ++v) {
    attribute->SetAttributeValue(draco::AttributeValueIndex(v), &mesh.positions[3 * v]);
  }

  draco::ExpertEncoder encoder(draco_mesh);
  // Sequential keeps face and point order (edgebreaker reorders both and drops
  // degenerate faces, which must reach ValidateMesh so that it can name them).
  encoder.SetEncodingMethod(options.method == DracoMethod::kSequential
                                ? draco::MESH_SEQUENTIAL_ENCODING
                                : draco::MESH_EDGEBREAKER_ENCODING);
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

namespace {

// A count of a Draco mesh header, read the way Draco 1.5.5 reads it
// (MeshSequentialDecoder / MeshEdgeBreakerDecoderImpl::DecodeConnectivity): a fixed
// uint32 in older bitstreams, a varint (Draco's own decoder) after.
bool ReadDeclaredCount(draco::DecoderBuffer* buffer, bool fixed_width, uint32_t* value) {
  if (fixed_width) return buffer->Decode(value);
  return draco::DecodeVarint(value, buffer);
}

absl::Status DeclaredTooMany(const char* what, uint64_t declared, uint64_t allowed,
                             size_t payload_bytes) {
  return absl::InvalidArgumentError(
      absl::StrCat("invalid Draco mesh: its header declares ", declared, " ", what,
                   ", more than a ", payload_bytes, "-byte payload can encode (at most ", allowed,
                   "); refused before decoding, as Draco would allocate for all of them"));
}

}  // namespace

absl::Status CheckDracoDeclaredCounts(std::string_view bytes, const DracoDecodeLimits& limits) {
  draco::DecoderBuffer buffer;
  buffer.Init(bytes.data(), bytes.size());
  char magic[5];
  uint8_t major = 0;
  uint8_t minor = 0;
  uint8_t encoder_type = 0;
  uint8_t encoder_method = 0;
  uint16_t flags = 0;
  if (!buffer.Decode(magic, 5) || std::string_view(magic, 5) != "DRACO" || !buffer.Decode(&major) ||
      !buffer.Decode(&minor) || !buffer.Decode(&encoder_type) || !buffer.Decode(&encoder_method) ||
      !buffer.Decode(&flags)) {
    return absl::OkStatus();  // not a Draco header: the decoder says so
  }
  if (encoder_type != draco::TRIANGULAR_MESH) return absl::OkStatus();
  const uint16_t version = DRACO_BITSTREAM_VERSION(major, minor);
  if (version > draco::kDracoMeshBitstreamVersion) return absl::OkStatus();  // Draco refuses it
  buffer.set_bitstream_version(version);
  if (version >= DRACO_BITSTREAM_VERSION(1, 3) && (flags & METADATA_FLAG_MASK) != 0) {
    draco::MetadataDecoder metadata_decoder;
    draco::GeometryMetadata metadata;
    if (!metadata_decoder.DecodeGeometryMetadata(&buffer, &metadata)) return absl::OkStatus();
  }

  const uint64_t by_size =
      std::max<uint64_t>(limits.always_allowed_faces,
                         limits.max_faces_per_byte > UINT64_MAX / std::max<size_t>(bytes.size(), 1)
                             ? UINT64_MAX
                             : limits.max_faces_per_byte * bytes.size());
  const uint64_t allowed = std::min<uint64_t>(by_size, limits.max_faces);

  if (encoder_method == draco::MESH_SEQUENTIAL_ENCODING) {
    const bool fixed = version < DRACO_BITSTREAM_VERSION(2, 2);
    uint32_t num_faces = 0;
    uint32_t num_points = 0;
    if (!ReadDeclaredCount(&buffer, fixed, &num_faces) ||
        !ReadDeclaredCount(&buffer, fixed, &num_points)) {
      return absl::OkStatus();
    }
    if (num_faces > allowed) return DeclaredTooMany("faces", num_faces, allowed, bytes.size());
    // Points past the faces' corners are unused vertices: allowed, within the same bound.
    if (num_points > allowed && num_points > 3 * uint64_t{num_faces}) {
      return DeclaredTooMany("points", num_points, std::max(allowed, 3 * uint64_t{num_faces}),
                             bytes.size());
    }
    return absl::OkStatus();
  }
  if (encoder_method != draco::MESH_EDGEBREAKER_ENCODING) return absl::OkStatus();

  uint8_t traversal_decoder_type = 0;  // MeshEdgebreakerDecoder::InitializeDecoder
  if (!buffer.Decode(&traversal_decoder_type)) return absl::OkStatus();
  const bool fixed = version < DRACO_BITSTREAM_VERSION(2, 0);
  uint32_t num_new_vertices = 0;
  if (version < DRACO_BITSTREAM_VERSION(2, 2) &&
      !ReadDeclaredCount(&buffer, fixed, &num_new_vertices)) {
    return absl::OkStatus();
  }
  uint32_t num_encoded_vertices = 0;
  uint32_t num_faces = 0;
  uint8_t num_attribute_data = 0;
  uint32_t num_encoded_symbols = 0;
  uint32_t num_encoded_split_symbols = 0;
  if (!ReadDeclaredCount(&buffer, fixed, &num_encoded_vertices) ||
      !ReadDeclaredCount(&buffer, fixed, &num_faces) || !buffer.Decode(&num_attribute_data) ||
      !ReadDeclaredCount(&buffer, fixed, &num_encoded_symbols) ||
      !ReadDeclaredCount(&buffer, fixed, &num_encoded_split_symbols)) {
    return absl::OkStatus();
  }
  if (num_faces > allowed) return DeclaredTooMany("faces", num_faces, allowed, bytes.size());
  // Every vertex is a corner of some face, and a split symbol is one of the symbols, so
  // the counts of a real mesh stay within the faces'; Draco sizes its tables by the sum.
  const uint64_t corners = 3 * uint64_t{num_faces};
  if (uint64_t{num_encoded_vertices} + num_encoded_split_symbols > corners + 3) {
    return absl::InvalidArgumentError(
        absl::StrCat("invalid Draco mesh: its header declares ", num_encoded_vertices,
                     " vertices and ", num_encoded_split_symbols, " split symbols for ", num_faces,
                     " faces (a mesh has at most 3 vertices per face)"));
  }
  if (num_new_vertices > corners + 3) {
    return absl::InvalidArgumentError(absl::StrCat("invalid Draco mesh: its header declares ",
                                                   num_new_vertices, " new vertices for ",
                                                   num_faces, " faces"));
  }
  if (num_attribute_data > limits.max_attribute_connectivities) {
    return absl::InvalidArgumentError(
        absl::StrCat("invalid Draco mesh: its header declares ", int{num_attribute_data},
                     " attributes with their own connectivity (at most ",
                     limits.max_attribute_connectivities, " accepted)"));
  }
  return absl::OkStatus();
}

absl::StatusOr<TriangleMesh> DecodeDracoMesh(std::string_view bytes) {
  MLCLUST_ASSIGN_OR_RETURN(DecodedDracoMesh decoded, DecodeDracoMeshWithFaceIds(bytes));
  return std::move(decoded.mesh);
}

absl::StatusOr<DecodedDracoMesh> DecodeDracoMeshWithFaceIds(std::string_view bytes,
                                                            const DracoDecodeLimits& limits) {
  if (bytes.empty()) return absl::InvalidArgumentError("Draco data is empty");
  MLCLUST_RETURN_IF_ERROR(CheckDracoDeclaredCounts(bytes, limits));
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
  // A hostile payload can declare more than it holds; Draco allocates before it finds the
  // data missing. The budget bounds what it may ask for by the payload's size, and a
  // failed allocation must not take the server down.
  const uint64_t budget = std::max<uint64_t>(
      limits.min_decode_budget_bytes, limits.decode_budget_per_byte > UINT64_MAX / bytes.size()
                                          ? UINT64_MAX
                                          : limits.decode_budget_per_byte * bytes.size());
  try {
    ScopedAllocationBudget allocation_budget(budget);
    draco::Decoder decoder;
    auto result = decoder.DecodeMeshFromBuffer(&buffer);
    if (!result.ok() && !allocation_budget.exceeded()) {
      return absl::InvalidArgumentError(
          absl::StrCat("invalid Draco mesh: ", result.status().error_msg_string()));
    }
    if (result.ok()) decoded = std::move(result).value();
  } catch (const std::bad_alloc&) {
    // The budget refused an allocation: `decoded` stays null, reported below.
  }
  // Null here: Draco failed over the budget, or an allocation threw.
  if (decoded == nullptr) {
    return absl::InvalidArgumentError(
        absl::StrCat("invalid Draco mesh: decoding it asks for more memory than a ", bytes.size(),
                     "-byte payload can need (more than ", budget >> 20,
                     " MiB); its header or attributes declare more than the bytes hold"));
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
  // A number type: Draco would read bool positions (any byte of the payload) as bools to
  // convert them (undefined behaviour for bytes other than 0 and 1; found by fuzz_draco).
  if (position->data_type() < draco::DT_INT8 || position->data_type() > draco::DT_FLOAT64) {
    return absl::InvalidArgumentError(absl::StrCat("Draco POSITION attribute has data type ",
                                                   static_cast<int>(position->data_type()),
                                                   "; a number type is required"));
  }
  // A payload is one Draco mesh: bytes after it are a client's mistake (two files joined, a
  // length wrong), never data, and were taken silently before.
  if (buffer.remaining_size() > 0) {
    return absl::InvalidArgumentError(absl::StrCat(
        "Draco mesh: ", buffer.remaining_size(),
        " bytes after the end of the Draco data (it ends at byte ",
        bytes.size() - buffer.remaining_size(), " of ", bytes.size(), "); send one Draco mesh"));
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
  const draco::PointAttribute* face_ids = nullptr;
  if (const int id = decoded->GetAttributeIdByMetadataEntry("name", kDracoFaceIdAttributeName);
      id >= 0) {
    face_ids = decoded->attribute(id);
    MLCLUST_RETURN_IF_ERROR(CheckFaceIdAttribute(*face_ids, num_points));
    // The header's encoder method, byte 8 after "DRACO", major, minor and type.
    if (bytes.size() > 8 && bytes[8] == draco::MESH_SEQUENTIAL_ENCODING) {
      return absl::InvalidArgumentError(absl::StrCat(
          "Draco mesh: the '", kDracoFaceIdAttributeName,
          "' attribute needs an edgebreaker payload; a sequential one keeps the face order "
          "without it (send it without the attribute)"));
    }
  }

  DecodedDracoMesh result;
  TriangleMesh& mesh = result.mesh;
  const size_t num_values = position->size();
  // Without face ids a vertex is a Draco point; with them each face has points of its
  // own, and a vertex is a position value (one per vertex of edgebreaker's connectivity).
  const size_t num_vertices = face_ids == nullptr ? num_points : num_values;
  if (num_vertices > kMaxMeshElements) {
    return absl::InvalidArgumentError(absl::StrCat("Draco mesh too large: ", num_vertices,
                                                   " positions (limit ", kMaxMeshElements, ")"));
  }
  mesh.positions.resize(3 * num_vertices);
  if (face_ids == nullptr) {
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
  } else {
    for (uint32_t v = 0; v < num_values; ++v) {
      if (!position->ConvertValue<float>(draco::AttributeValueIndex(v), 3,
                                         &mesh.positions[3 * size_t{v}])) {
        return absl::InvalidArgumentError(
            absl::StrCat("Draco mesh: position ", v, " is not readable"));
      }
    }
  }

  std::vector<uint32_t> decoded_indices(3 * num_faces);
  for (uint32_t f = 0; f < num_faces; ++f) {
    const draco::Mesh::Face& face = decoded->face(draco::FaceIndex(f));
    for (int c = 0; c < 3; ++c) {
      const uint32_t point = face[c].value();
      if (point >= num_points) {
        return absl::InvalidArgumentError(
            absl::StrCat("Draco mesh: face ", f, " corner ", c, " refers to point ", point,
                         ", but the mesh has ", num_points, " points"));
      }
      uint32_t vertex = point;
      if (face_ids != nullptr) {
        vertex = position->mapped_index(draco::PointIndex(point)).value();
        if (vertex >= num_values) {
          return absl::InvalidArgumentError(
              absl::StrCat("Draco mesh: point ", point, " has no readable position"));
        }
      }
      decoded_indices[3 * size_t{f} + c] = vertex;
    }
  }
  if (face_ids == nullptr) {
    mesh.indices = std::move(decoded_indices);
    return result;
  }

  // Put each face where its id says, checking that the ids are 0..F-1, once each.
  result.has_face_ids = true;
  result.original_face.resize(num_faces);
  mesh.indices.assign(3 * size_t{num_faces}, 0);
  std::vector<bool> seen(num_faces, false);
  for (uint32_t f = 0; f < num_faces; ++f) {
    const draco::Mesh::Face& face = decoded->face(draco::FaceIndex(f));
    uint32_t id[3];
    for (int c = 0; c < 3; ++c) {
      const draco::AttributeValueIndex value = face_ids->mapped_index(face[c]);
      if (value.value() >= face_ids->size() ||
          !face_ids->ConvertValue<uint32_t>(value, 1, &id[c])) {
        return absl::InvalidArgumentError(absl::StrCat(
            "Draco mesh: face ", f, " corner ", c, " has no readable ", kDracoFaceIdAttributeName));
      }
    }
    if (id[0] != id[1] || id[0] != id[2]) {
      return absl::InvalidArgumentError(absl::StrCat(
          "Draco mesh: face ", f, " has different ", kDracoFaceIdAttributeName,
          " values on its corners (", id[0], ", ", id[1], ", ", id[2], "); the id is per face"));
    }
    if (id[0] >= num_faces) {
      return absl::InvalidArgumentError(
          absl::StrCat("Draco mesh: face ", f, " has ", kDracoFaceIdAttributeName, " ", id[0],
                       ", but the mesh has ", num_faces, " faces (ids must be 0..", num_faces - 1,
                       "; did the encoder drop degenerate faces?)"));
    }
    if (seen[id[0]]) {
      return absl::InvalidArgumentError(absl::StrCat("Draco mesh: ", kDracoFaceIdAttributeName, " ",
                                                     id[0], " is on more than one face"));
    }
    seen[id[0]] = true;
    result.original_face[f] = id[0];
    for (int c = 0; c < 3; ++c)
      mesh.indices[3 * size_t{id[0]} + c] = decoded_indices[3 * size_t{f} + c];
  }
  return result;
}

}  // namespace mlclust
