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

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"
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

// How much a payload may declare and make the decoder allocate. Draco 1.5.5 sizes its
// edgebreaker corner table, the sequential decoder's points and every attribute from the
// counts a payload declares, before it finds the data missing: 110 bytes declaring 354M
// faces made it write 8.4 GB. A legitimate payload cannot declare more than its bytes can
// encode, so the declared counts are bounded by the payload's size, and what decoding may
// allocate by a budget in proportion to it (allocation_budget.h) for what the header does
// not say (attribute sizes, metadata). Measured (bench: the BENCHMARKS.md section "Draco
// payload limits"): real meshes are 0.3–3 faces per byte (bunny00: 0.34 at 8-bit
// positions); the most compressible mesh we could make, a 2M-face regular grid, is 16
// faces per byte at 8-bit positions, 95 at 4-bit and 1,565 at 1-bit (both refused: their
// faces collapse onto a few positions); decoding takes 60–110 bytes per face, 360 with
// the face id attribute.
struct DracoDecodeLimits {
  // Faces (and points) a payload may declare per byte of payload.
  uint64_t max_faces_per_byte = 64;
  // Up to this a payload may declare any count (a small mesh is never refused for its
  // ratio); 65,536 faces cost Draco about 3 MB.
  uint64_t always_allowed_faces = uint64_t{1} << 16;
  // Never more than this, whatever the payload's size (ids are 32-bit).
  uint64_t max_faces = kMaxMeshElements;
  // Attributes with their own connectivity (seams) an edgebreaker payload may declare;
  // Draco keeps a corner table's worth of data for each.
  uint32_t max_attribute_connectivities = 16;
  // What decoding may ask of operator new in all (counted, not net):
  // max(min_decode_budget_bytes, decode_budget_per_byte * payload bytes). 64 faces per
  // byte at 360 bytes per face is 23 KiB per byte.
  uint64_t decode_budget_per_byte = 32 * 1024;
  uint64_t min_decode_budget_bytes = uint64_t{64} << 20;
};

// Reads the header of a Draco mesh payload (every bitstream version Draco 1.5.5 decodes:
// 1.0 to 2.2, sequential and edgebreaker, metadata skipped) and checks its declared counts
// against `limits`. OK for bytes that are not a Draco mesh at all: the decoder names those.
// Reads no more than the header; allocates nothing in proportion to what it declares.
absl::Status CheckDracoDeclaredCounts(std::string_view bytes, const DracoDecodeLimits& limits = {});

// DecodeDracoMesh, also saying whether the payload carried face ids and how the bytes
// ordered the faces (for a server that reports it, and for tests). Before Draco decodes,
// the header's declared counts are checked against `limits` (INVALID_ARGUMENT naming the
// count, what was declared and what the payload's size allows).
absl::StatusOr<DecodedDracoMesh> DecodeDracoMeshWithFaceIds(std::string_view bytes,
                                                            const DracoDecodeLimits& limits = {});

}  // namespace mlclust

#endif  // MLCLUST_CORE_IO_DRACO_CODEC_H_
