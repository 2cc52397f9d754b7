// GrowSeedsInRoundsGpu (seed_growth.h): one round of section 5.2's growth (Fig. 5.9),
// after the prelude of gpu/context/compute.h. Jacobi: every face reads the labels of the
// round before (`before`) and writes its label of this round (`after`); the host swaps
// the two buffers between rounds.
//
// A free face (0xFFFFFFFF) takes the smallest label among its edge-neighbours; a face
// with none in a cluster stays free, as does the missing neighbour across a boundary edge
// (also 0xFFFFFFFF, the largest value, so min() alone does both). Each face that joins
// adds one to `assigned`, the faces assigned so far; a round that leaves it unchanged
// ends the growth.
layout(std430, binding = 0) readonly buffer Neighbours { uint neighbours[]; };  // 3 per face
layout(std430, binding = 1) readonly buffer Before { uint before[]; };          // round r - 1
layout(std430, binding = 2) writeonly buffer After { uint after[]; };           // round r
layout(std430, binding = 3) buffer Assigned { uint assigned; };
layout(location = 0) uniform uint u_face_begin;  // first face of this dispatch
layout(location = 1) uniform uint u_face_end;    // one past its last
const uint kFree = 0xFFFFFFFFu;

void main() {
  uint face = u_face_begin + LinearInvocationIndex();
  if (face >= u_face_end) return;
  uint label = before[face];
  if (label == kFree) {
    for (uint edge = 0u; edge < 3u; ++edge) {
      uint neighbour = neighbours[3u * face + edge];
      if (neighbour != kFree) label = min(label, before[neighbour]);
    }
    if (label != kFree) atomicAdd(assigned, 1u);
  }
  after[face] = label;
}
