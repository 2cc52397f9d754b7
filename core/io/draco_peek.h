// What a Draco payload says about itself before it is decoded: its geometry type, its
// connectivity method and whether it carries the per-face id attribute
// (core/io/draco_codec.h, kDracoFaceIdAttributeName). The server reads this when it accepts a
// job, to tell the client how element ids will relate to its faces (Accepted.face_order)
// without decoding the mesh first.
//
// Only the header (11 bytes) and, where the header's flag says so, the geometry metadata
// that follows it are read: O(metadata bytes), no connectivity or attribute is decoded.
// Untrusted input: bytes that are not a Draco header give `is_draco = false`; nothing is
// assumed beyond what the bytes hold. The decoder has the last word: a payload that names
// the id attribute in its metadata but whose ids are bad is refused when decoded.
#ifndef MLCLUST_CORE_IO_DRACO_PEEK_H_
#define MLCLUST_CORE_IO_DRACO_PEEK_H_

#include <string>
#include <string_view>

namespace mlclust {

struct DracoPayloadFacts {
  bool is_draco = false;  // a Draco header was read
  bool is_mesh = false;   // ... of a triangle mesh (not a point cloud)
  // "sequential" or "edgebreaker" for meshes; "" otherwise.
  std::string method;
  // Some attribute's metadata has "name" = kDracoFaceIdAttributeName.
  bool names_face_ids = false;
};

DracoPayloadFacts PeekDracoPayload(std::string_view bytes);

// One sentence for a client about how element ids relate to its faces, from `facts`:
// "element ids are the face ids the payload carries (attribute mlclust_face_id)", or
// "element ids follow the decoded face order: ..." with what that means for the method.
std::string DescribeFaceOrder(const DracoPayloadFacts& facts);

}  // namespace mlclust

#endif  // MLCLUST_CORE_IO_DRACO_PEEK_H_
