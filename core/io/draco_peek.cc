#include "core/io/draco_peek.h"

#include <algorithm>
#include <new>

#include "core/io/allocation_budget.h"
#include "core/io/draco_codec.h"
#include "draco/compression/config/compression_shared.h"
#include "draco/compression/point_cloud/point_cloud_decoder.h"
#include "draco/core/decoder_buffer.h"
#include "draco/metadata/geometry_metadata.h"
#include "draco/metadata/metadata_decoder.h"

namespace mlclust {

DracoPayloadFacts PeekDracoPayload(std::string_view bytes) {
  DracoPayloadFacts facts;
  draco::DecoderBuffer buffer;
  buffer.Init(bytes.data(), bytes.size());
  draco::DracoHeader header;
  if (!draco::PointCloudDecoder::DecodeHeader(&buffer, &header).ok()) return facts;
  facts.is_draco = true;
  facts.is_mesh = header.encoder_type == draco::TRIANGULAR_MESH;
  if (facts.is_mesh) {
    facts.method = header.encoder_method == draco::MESH_EDGEBREAKER_ENCODING  ? "edgebreaker"
                   : header.encoder_method == draco::MESH_SEQUENTIAL_ENCODING ? "sequential"
                                                                              : "";
  }
  // As PointCloudDecoder::Decode: metadata exists from bitstream 1.3 on, right after the
  // header, where the header's flag says so.
  const uint16_t version = DRACO_BITSTREAM_VERSION(header.version_major, header.version_minor);
  if (version < DRACO_BITSTREAM_VERSION(1, 3) || (header.flags & METADATA_FLAG_MASK) == 0) {
    return facts;
  }
  buffer.set_bitstream_version(version);
  // This runs on the server's network thread for untrusted bytes: a backstop as around the
  // decoder (core/io/allocation_budget.h), though Draco 1.5.5's metadata decoder checks
  // declared sizes against the bytes left. A payload over it is read as naming no face ids
  // (its decoding then says what is wrong).
  try {
    ScopedAllocationBudget allocation_budget(std::max<size_t>(size_t{1} << 20, 4 * bytes.size()));
    draco::GeometryMetadata metadata;
    draco::MetadataDecoder decoder;
    if (!decoder.DecodeGeometryMetadata(&buffer, &metadata)) return facts;
    for (const auto& attribute : metadata.attribute_metadatas()) {
      std::string name;
      if (attribute != nullptr && attribute->GetEntryString("name", &name) &&
          name == kDracoFaceIdAttributeName) {
        facts.names_face_ids = true;
      }
    }
  } catch (const std::bad_alloc&) {
    facts.names_face_ids = false;
  }
  return facts;
}

std::string DescribeFaceOrder(const DracoPayloadFacts& facts) {
  if (!facts.is_draco || !facts.is_mesh) return "";
  if (facts.names_face_ids) {
    return std::string("element ids are the face ids the payload carries (attribute ") +
           kDracoFaceIdAttributeName + "): the faces in the order they had before encoding";
  }
  if (facts.method == "sequential") {
    return "element ids follow the decoded face order (no face id attribute); sequential "
           "encoding keeps the encoder's face order";
  }
  return "element ids follow the decoded face order (no face id attribute); " + facts.method +
         " encoding reorders faces, so they are not the encoder's input order: add the face id "
         "attribute to map labels back (README, For pipelines)";
}

}  // namespace mlclust
