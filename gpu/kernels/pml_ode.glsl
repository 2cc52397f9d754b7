// PML and HC on the GPU (pml_levels.h, hc_levels.h): the mesh's part of the optimal dual
// edges (ode_min.glsl): one edge per directed cluster edge (src, dst), offered to src
// only (the reverse edge offers itself to dst), its cost CvdMergeCost. After
// pml_cvd.glsl, before ode_min.glsl.
layout(std430, binding = 4) readonly buffer Edges { uint edges[]; };  // (src, dst) per edge
layout(std430, binding = 6) buffer EdgeKeys { uint edge_keys[]; };    // (high, low) per edge
const bool kBothEnds = false;

bool DualEdge(uint i, out uint a, out uint b) {
  a = edges[2u * i];
  b = edges[2u * i + 1u];
  return true;
}

double DualEdgeCost(uint a, uint b) { return CvdMergeCost(a, b); }
