// Draco compression of meshes for the wire.
//
// Element ids on the wire are the client's face order. Draco's edgebreaker method
// reorders faces and vertices (and drops degenerate faces), so EncodeMeshToDraco uses the
// sequential method by default, which keeps both orders. A payload may instead carry
// each face's original index in a per-face id attribute (below); then edgebreaker, with
// quantisation, is safe: the decoder puts the faces back in the client's order.
//
// The face id attribute, for any encoder: a GENERIC attribute with 1 component of an
// integer type (uint32 is best), whose attribute metadata has the string entry
// "name" = "mlclust_face_id" (kDracoFaceIdAttributeName); all three corners of a face
// carry that face's original index 0..F-1. With Draco's mesh builders (draco3d's
// MeshBuilder, DracoPy) that means one point per corner (3F points: positions and ids
// per corner) and the encoder's own deduplication (draco3d's encoder and the draco
// tools do it) welding the corners back into vertices by equal position.
#ifndef MLCLUST_CORE_IO_DRACO_CODEC_H_
#define MLCLUST_CORE_IO_DRACO_CODEC_H_

#include <string>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"
#include "core/mesh/mesh.h"

namespace mlclust {

// The metadata "name" of the per-face id attribute.
inline constexpr char kDracoFaceIdAttributeName[] = "mlclust_face_id";

enum class DracoMethod {
  kSequential,   // keeps face and vertex order and every face as sent
  kEdgebreaker,  // Draco's default: several times smaller connectivity, reorders faces
};

struct DracoEncodeOptions {
  // Position quantization in bits; 0 keeps float32 positions exactly (the default, so
  // that energies computed on the server match the client's own mesh bit for bit).
  int position_quantization_bits = 0;
  // Draco's speed/ratio trade-off, 0 (best compression) .. 10 (fastest). Below 10 the
  // face indices are delta and entropy coded; 10 sends them as raw 8/16/32-bit values.
  int speed = 5;
  DracoMethod method = DracoMethod::kSequential;
  // Writes the per-face id attribute (kDracoFaceIdAttributeName) so that the decoder
  // restores the face order. Needed with kEdgebreaker for labels to mean the client's
  // faces; refused with kSequential, which keeps the order without it.
  bool write_face_ids = false;
};

// Encodes `mesh`. With the sequential method (the default) face i and vertex v keep their indices,
// and nothing is cleaned up on the way (degenerate faces, duplicate faces, vertices at equal
// positions and unused vertices all arrive as sent, so that ValidateMesh on the other
// side sees what the client had). With position_quantization_bits == 0 positions arrive
// bit for bit, NaN included. With kEdgebreaker Draco reorders faces and vertices, splits
// non-manifold vertices and drops degenerate faces and unused vertices; with
// write_face_ids the decoder restores the face order (and reports a dropped face).
// INVALID_ARGUMENT for an out-of-range option, write_face_ids with kSequential, an index out of
// range, a mesh with vertices but no faces (Draco 1.5.5 cannot decode what it makes of one), or a
// non-finite coordinate when quantizing.
absl::StatusOr<std::string> EncodeMeshToDraco(const TriangleMesh& mesh,
                                              const DracoEncodeOptions& options = {});

// Decodes a Draco triangle mesh. Faces come in the client's order: where the payload
// carries the face id attribute, face i of the result is the face whose id is i (the ids
// must be 0..F-1, each once, the same on a face's three corners); otherwise in the order
// the bytes hold them. Vertices: without face ids, vertex i is Draco point i (its
// position followed through the attribute's point-to-value map); with face ids (where
// each face has its own points), vertex i is POSITION value i, which is one per vertex
// for edgebreaker payloads; a sequential payload with face ids is refused, as it cannot
// say which corners share a vertex (send it without ids: sequential keeps the order).
// Untrusted input: INVALID_ARGUMENT with Draco's message for bytes that are not a Draco
// mesh (a point cloud is refused too), or a mesh without 3-component positions, or bad
// face ids; never crashes on random or truncated bytes. The result is not validated:
// call ValidateMesh.
absl::StatusOr<TriangleMesh> DecodeDracoMesh(std::string_view bytes);

struct DecodedDracoMesh {
  TriangleMesh mesh;  // as DecodeDracoMesh returns it: faces in the client's order
  // Whether the payload carried the face id attribute.
  bool has_face_ids = false;
  // With face ids: original_face[d] is the id of the d-th face the bytes hold (so the
  // payload's order is recoverable); empty without.
  std::vector<uint32_t> original_face;
};

// DecodeDracoMesh, also saying whether the payload carried face ids and how the bytes
// ordered the faces (for a server that reports it, and for tests).
absl::StatusOr<DecodedDracoMesh> DecodeDracoMeshWithFaceIds(std::string_view bytes);

}  // namespace mlclust

#endif  // MLCLUST_CORE_IO_DRACO_CODEC_H_
