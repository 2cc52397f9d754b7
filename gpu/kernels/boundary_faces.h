// Boundary faces of a face clustering: the faces with at least one edge-neighbour in
// another cluster. These are the only faces BB re-decides (Alg. 5.1) and the only ones
// whose moves EMLO considers (Alg. 3.3), so every GPU optimiser starts from this flag.
#ifndef MLCLUST_GPU_KERNELS_BOUNDARY_FACES_H_
#define MLCLUST_GPU_KERNELS_BOUNDARY_FACES_H_

#include <cstdint>
#include <span>
#include <vector>

#include "absl/status/statusor.h"
#include "core/base/ids.h"
#include "core/mesh/mesh.h"
#include "gpu/context/gl_context.h"

namespace mlclust::gpu {

// Returns one byte per face: 1 if some neighbour across an edge (FaceId::Invalid() across
// a mesh boundary edge counts as none) has a label other than the face's own, else 0.
// Labels are compared for equality only; any value, ClusterId::Invalid() included, is a
// label. The result equals FlagBoundaryFacesCpu's exactly.
//
// Runs on `context` (current thread: its owner). Returns
//   INVALID_ARGUMENT if labels.size() != adjacency.num_faces(), a neighbour id is neither
//     Invalid() nor < num_faces, or there are more than kMaxMeshElements faces;
//   RESOURCE_EXHAUSTED if the labels (4 bytes per face, needed whole because neighbours
//     reach anywhere) exceed context.max_storage_buffer_bytes() or GPU memory runs out;
//   FAILED_PRECONDITION on a thread other than the context's; INTERNAL on GL errors.
// Adjacency is streamed in chunks that fit the storage buffer limit.
absl::StatusOr<std::vector<uint8_t>> FlagBoundaryFaces(GlContext& context,
                                                       const FaceAdjacency& adjacency,
                                                       std::span<const ClusterId> labels);

// The bytes of GPU memory FlagBoundaryFaces allocates for `num_faces` faces on `context`
// (labels, one chunk of adjacency, one chunk of flags): for a caller that budgets GPU
// memory before it submits work.
uint64_t FlagBoundaryFacesMemoryBound(const GlContext& context, uint64_t num_faces);

// OK, or INVALID_ARGUMENT naming the first neighbour id that is neither FaceId::Invalid()
// nor < num_faces: what every kernel reading the adjacency by index checks first (an
// out-of-range index is an out-of-bounds read in a shader, undefined in GL).
absl::Status CheckNeighboursInRange(const FaceAdjacency& adjacency);

// The CPU reference of FlagBoundaryFaces, with the same result. Expects
// labels.size() == adjacency.num_faces() and every neighbour Invalid() or in range
// (asserted, not checked: this is the fallback for inputs core already validated).
std::vector<uint8_t> FlagBoundaryFacesCpu(const FaceAdjacency& adjacency,
                                          std::span<const ClusterId> labels);

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_KERNELS_BOUNDARY_FACES_H_
