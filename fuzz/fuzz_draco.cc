// The Draco payload of a mesh job, as the server takes it from the wire: peeked at when the
// job is accepted (core/io/draco_peek.h, on the network thread), decoded (with or without
// the per-face id attribute), then validated; a mesh that passes gets its face adjacency and
// measures, as every mesh job does next.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "core/io/draco_codec.h"
#include "core/io/draco_peek.h"
#include "core/mesh/face_measures.h"
#include "core/mesh/mesh.h"
#include "fuzz/fuzz_check.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace mlclust;
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  const DracoPayloadFacts facts = PeekDracoPayload(bytes);
  MLCLUST_FUZZ_CHECK(facts.is_draco || !facts.names_face_ids);
  absl::StatusOr<DecodedDracoMesh> decoded = DecodeDracoMeshWithFaceIds(bytes);
  if (!decoded.ok()) {
    MLCLUST_FUZZ_CHECK(decoded.status().code() == absl::StatusCode::kInvalidArgument);
    return 0;
  }
  // What the peek told the client at acceptance holds for a payload that decodes.
  MLCLUST_FUZZ_CHECK(facts.is_draco && facts.is_mesh);
  MLCLUST_FUZZ_CHECK(!decoded->has_face_ids || facts.names_face_ids);
  const TriangleMesh& mesh = decoded->mesh;
  MLCLUST_FUZZ_CHECK(mesh.positions.size() % 3 == 0 && mesh.indices.size() % 3 == 0);
  if (decoded->has_face_ids) {
    MLCLUST_FUZZ_CHECK(decoded->original_face.size() == mesh.num_faces());
  } else {
    MLCLUST_FUZZ_CHECK(decoded->original_face.empty());
  }
  if (!ValidateMesh(mesh).ok()) return 0;
  MLCLUST_FUZZ_CHECK(CheckVertexIndices(mesh).ok());
  absl::StatusOr<FaceAdjacency> adjacency = BuildFaceAdjacency(mesh);
  MLCLUST_FUZZ_CHECK(adjacency.ok());
  const FaceMeasures measures = ComputeFaceMeasures(mesh);
  (void)measures;
  return 0;
}
