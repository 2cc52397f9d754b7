// ML/PML for points on the GPU (points_levels.h): the points' part of the optimal dual
// edges (ode_min.glsl) over every cluster's local neighbours and the clusters that list
// it as theirs (the CPU's ForEachCandidate: the dual edges are symmetric). One edge per
// neighbour slot (cluster c, slot s), offered to both ends; its cost WardCost. After
// points_common.glsl, before ode_min.glsl.
layout(std430, binding = 4) readonly buffer Neighbours { uint neighbours[]; };  // k x 2d
layout(std430, binding = 16) buffer EdgeKeys { uint edge_keys[]; };  // (high, low) per slot
const bool kBothEnds = true;

bool DualEdge(uint i, out uint a, out uint b) {
  a = i / (2u * u_dims);
  b = neighbours[i];
  return b != kNone && counts[a] != 0u && counts[b] != 0u;
}

double DualEdgeCost(uint a, uint b) { return WardCost(a, b); }
