// ML/PML for points on the GPU (points_levels.h): the points' part of the optimal dual
// edges (ode_min.glsl) over every cluster's local neighbours and the clusters that list
// it as theirs (the CPU's ForEachCandidate: the dual edges are symmetric). One edge per
// neighbour slot (cluster c, slot s), offered to both ends; its cost WardCost. With
// u_needed_at (HC's and ML's steps, points_hc.glsl) only the edges with an end whose step
// flag (binding 18 from that offset) is set: the other clusters' ODEs are left partial
// and are not read. After points_common.glsl, before ode_min.glsl.
layout(std430, binding = 4) readonly buffer Neighbours { uint neighbours[]; };  // k x 2d
layout(std430, binding = 16) buffer EdgeKeys { uint edge_keys[]; };  // (high, low) per slot
layout(std430, binding = 18) readonly buffer StepWork { uint step_work[]; };
layout(location = 9) uniform uint u_needed_at;  // 0: every edge
const bool kBothEnds = true;

bool DualEdge(uint i, out uint a, out uint b) {
  a = i / (2u * u_dims);
  b = neighbours[i];
  if (b == kNone || counts[a] == 0u || counts[b] == 0u) return false;
  return u_needed_at == 0u || step_work[u_needed_at + a] != 0u || step_work[u_needed_at + b] != 0u;
}

double DualEdgeCost(uint a, uint b) { return WardCost(a, b); }
