// PML on the GPU (pml_levels.h): every cluster's optimal dual edge (Def. 4.2), the
// cheapest merge cost over its boundary face edges, equal costs to the larger id (the
// CPU's CheaperDualEdge, core/cluster/detail/ode_heap.h). Without 64-bit atomics the
// minimum of a double is taken in three 32-bit passes over the directed edges, on an
// order-preserving key of the cost's bits (exact: no rounding to float):
//   phase 3 (per cluster)  reset: key (~0, ~0), partner none (0)
//   phase 0 (per edge)     cost, its key; atomicMin of the key's high word
//   phase 1 (per edge)     where the high word is the minimum: atomicMin of the low word
//   phase 2 (per edge)     where the whole key is the minimum: atomicMax of partner + 1
// After pml_cvd.glsl.
layout(std430, binding = 4) readonly buffer Edges { uint edges[]; };  // (src, dst) per edge
layout(std430, binding = 6) buffer EdgeKeys { uint edge_keys[]; };    // (high, low) per edge
layout(std430, binding = 7) buffer Odes { uint odes[]; };  // (high, low, partner + 1) per cluster
layout(location = 0) uniform uint u_count;  // edges (phases 0-2) or clusters (phase 3)
layout(location = 1) uniform uint u_phase;

void main() {
  uint i = LinearInvocationIndex();
  if (i >= u_count) return;
  if (u_phase == 3u) {
    odes[3u * i] = 0xFFFFFFFFu;
    odes[3u * i + 1u] = 0xFFFFFFFFu;
    odes[3u * i + 2u] = 0u;
    return;
  }
  uint a = edges[2u * i];
  uint b = edges[2u * i + 1u];
  if (u_phase == 0u) {
    double cost = CvdMergeCost(a, b);
    if (cost == 0.0LF) cost = 0.0LF;  // -0 and +0 are one cost, as for the CPU's ==
    uvec2 bits = unpackDouble2x32(cost);  // x: low word, y: high word
    bool negative = (bits.y & 0x80000000u) != 0u;
    uint high = negative ? ~bits.y : (bits.y | 0x80000000u);
    uint low = negative ? ~bits.x : bits.x;
    edge_keys[2u * i] = high;
    edge_keys[2u * i + 1u] = low;
    atomicMin(odes[3u * a], high);
  } else if (u_phase == 1u) {
    if (edge_keys[2u * i] == odes[3u * a]) atomicMin(odes[3u * a + 1u], edge_keys[2u * i + 1u]);
  } else {
    if (edge_keys[2u * i] == odes[3u * a] && edge_keys[2u * i + 1u] == odes[3u * a + 1u]) {
      atomicMax(odes[3u * a + 2u], b + 1u);
    }
  }
}
