// Draco compression of meshes for the wire.
//
// Element ids on the wire are the client's face order. Draco's edgebreaker method
// reorders faces and vertices (and drops degenerate faces), so EncodeMeshToDraco uses the
// sequential method, which keeps both orders; DecodeDracoMesh returns faces in the order
// the bytes hold them, whatever method made them.
#ifndef MLCLUST_CORE_IO_DRACO_CODEC_H_
#define MLCLUST_CORE_IO_DRACO_CODEC_H_

#include <string>
#include <string_view>

#include "absl/status/statusor.h"
#include "core/mesh/mesh.h"

namespace mlclust {

struct DracoEncodeOptions {
  // Position quantization in bits; 0 keeps float32 positions exactly (the default, so
  // that energies computed on the server match the client's own mesh bit for bit).
  int position_quantization_bits = 0;
  // Draco's speed/ratio trade-off, 0 (best compression) .. 10 (fastest). Below 10 the
  // face indices are delta and entropy coded; 10 sends them as raw 8/16/32-bit values.
  int speed = 5;
};

// Encodes with the sequential method: face i and vertex v keep their indices, and
// nothing is cleaned up on the way (degenerate faces, duplicate faces, vertices at equal
// positions and unused vertices all arrive as sent, so that ValidateMesh on the other
// side sees what the client had). With position_quantization_bits == 0 positions arrive
// bit for bit, NaN included.
// INVALID_ARGUMENT for an out-of-range option, an index out of range, a mesh with
// vertices but no faces (Draco 1.5.5 cannot decode what it makes of one), or a
// non-finite coordinate when quantizing.
absl::StatusOr<std::string> EncodeMeshToDraco(const TriangleMesh& mesh,
                                              const DracoEncodeOptions& options = {});

// Decodes a Draco triangle mesh: vertex i is Draco point i (its position followed
// through the attribute's point-to-value map), faces in the order the bytes hold them.
// Untrusted input: INVALID_ARGUMENT with Draco's message for bytes that are not a Draco
// mesh (a point cloud is refused too), or a mesh without 3-component positions; never
// crashes on random or truncated bytes. The result is not validated: call ValidateMesh.
absl::StatusOr<TriangleMesh> DecodeDracoMesh(std::string_view bytes);

}  // namespace mlclust

#endif  // MLCLUST_CORE_IO_DRACO_CODEC_H_
