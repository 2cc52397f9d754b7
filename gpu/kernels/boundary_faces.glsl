// FlagBoundaryFaces (boundary_faces.h): the body of the compute shader, after the prelude
// of gpu/context/compute.h (#version, work group size, LinearInvocationIndex()). Embedded
// in the library at build time (gpu/kernels/CMakeLists.txt).
//
// One invocation per 4 faces: GLSL has no 8-bit stores without extensions, so each
// invocation packs its four flags into one uint (face 4w + k in byte k; the host reads
// bytes of a little-endian word, which every platform we target is). No atomics needed,
// and the readback is one byte per face.
layout(std430, binding = 0) readonly buffer Labels { uint labels[]; };          // all faces
layout(std430, binding = 1) readonly buffer Neighbours { uint neighbours[]; };  // 3 per chunk face
layout(std430, binding = 2) writeonly buffer Flags { uint flags[]; };           // 4 chunk faces per word
layout(location = 0) uniform uint u_face_begin;  // first face of the chunk
layout(location = 1) uniform uint u_face_count;  // faces in the chunk
const uint kInvalidFace = 0xFFFFFFFFu;

void main() {
  uint word = LinearInvocationIndex();
  uint first = word * 4u;
  if (first >= u_face_count) return;
  uint last = min(first + 4u, u_face_count);
  uint word_flags = 0u;
  for (uint local = first; local < last; ++local) {
    uint label = labels[u_face_begin + local];
    bool boundary = false;
    for (uint edge = 0u; edge < 3u; ++edge) {
      uint neighbour = neighbours[3u * local + edge];
      boundary = boundary || (neighbour != kInvalidFace && labels[neighbour] != label);
    }
    if (boundary) word_flags |= 1u << (8u * (local - first));
  }
  flags[word] = word_flags;
}
