// Per-face measures (area, centroid, unit normal) on the GPU: the first stage of every mesh
// job when the server has a GL context. Same inputs and outputs as ComputeFaceMeasures in
// core/mesh/face_measures.h.
#ifndef MLCLUST_GPU_KERNELS_FACE_MEASURES_GPU_H_
#define MLCLUST_GPU_KERNELS_FACE_MEASURES_GPU_H_

#include "absl/status/statusor.h"
#include "core/mesh/face_measures.h"
#include "core/mesh/mesh.h"
#include "gpu/context/gl_context.h"

namespace mlclust::gpu {

// Computes the measures of every face in double precision (GLSL 4.50 doubles from the
// float positions), with the same operations in the same order as ComputeFaceMeasures:
// cross = (b - a) x (c - a), area = |cross| / 2, centroid = (a + b + c) / 3,
// normal = cross / |cross|, or zero when |cross| == 0.
//
// Parity: a driver with IEEE double add, multiply, divide and sqrt (llvmpipe does) gives
// bit-identical results; the GLSL spec lets division and sqrt be less exact, so callers
// should expect agreement to a relative 1e-12 (per component, relative to the vector's
// norm), which the tests check.
//
// Checks what the shader would otherwise read out of bounds, in O(faces) on the CPU:
//   INVALID_ARGUMENT if positions or indices are not whole triples, a vertex index is out
//     of range, or there are more than kMaxMeshElements faces or vertices;
//   RESOURCE_EXHAUSTED if the positions (12 bytes per vertex, needed whole) exceed
//     context.max_storage_buffer_bytes() or GPU memory runs out;
//   FAILED_PRECONDITION on a thread other than the context's; INTERNAL on GL errors.
// Degenerate faces are not rejected (they get area 0 and a zero normal, as on the CPU).
// Faces are processed in chunks that fit the storage buffer limit.
absl::StatusOr<FaceMeasures> ComputeFaceMeasuresGpu(GlContext& context, const TriangleMesh& mesh);

// The bytes of GPU memory ComputeFaceMeasuresGpu allocates for a mesh of this size on
// `context` (positions, and one chunk of indices and of each output): for a caller that
// budgets GPU memory before it submits work.
uint64_t ComputeFaceMeasuresGpuMemoryBound(const GlContext& context, uint64_t num_faces,
                                           uint64_t num_vertices);

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_KERNELS_FACE_MEASURES_GPU_H_
