// PML and HC on the GPU, shared by the mesh (pml_ode.glsl) and point (points_ode.glsl)
// levels: every cluster's optimal dual edge (Def. 4.2), the cheapest merge cost over its
// dual edges, equal costs to the larger id (the CPU's CheaperDualEdge,
// core/cluster/detail/ode_heap.h). Without 64-bit atomics the minimum of a double is
// taken in three 32-bit passes over the edges, on an order-preserving key of the cost's
// bits (exact: no rounding to float):
//   phase 3 (per cluster)  reset: key (~0, ~0), partner none (0)
//   phase 0 (per edge)     cost, its key; atomicMin of the key's high word at the ends
//   phase 1 (per edge)     where the high word is an end's minimum: atomicMin of the low
//   phase 2 (per edge)     where the whole key is an end's minimum: atomicMax of the other
//                          end + 1
// After the engine's part, which declares edge_keys (high, low per edge) and defines
// DualEdge(i, a, b) (edge i's ends, false where it offers nothing), DualEdgeCost(a, b)
// and kBothEnds (whether an edge offers itself to b as well as to a).
layout(std430, binding = 7) buffer Odes { uint odes[]; };  // (high, low, partner + 1) per cluster
layout(location = 0) uniform uint u_count;  // edges (phases 0-2) or clusters (phase 3)
layout(location = 1) uniform uint u_phase;

// Phase 0 at end a: the key's high word.
void OfferHigh(uint a, uint high) { atomicMin(odes[3u * a], high); }

// Phase 1 at end a.
void OfferLow(uint a, uint high, uint low) {
  if (high == odes[3u * a]) atomicMin(odes[3u * a + 1u], low);
}

// Phase 2 at end a, the other end b.
void OfferPartner(uint a, uint b, uint high, uint low) {
  if (high == odes[3u * a] && low == odes[3u * a + 1u]) atomicMax(odes[3u * a + 2u], b + 1u);
}

void main() {
  uint i = LinearInvocationIndex();
  if (i >= u_count) return;
  if (u_phase == 3u) {
    odes[3u * i] = 0xFFFFFFFFu;
    odes[3u * i + 1u] = 0xFFFFFFFFu;
    odes[3u * i + 2u] = 0u;
    return;
  }
  uint a;
  uint b;
  if (!DualEdge(i, a, b)) return;
  if (u_phase == 0u) {
    double cost = DualEdgeCost(a, b);
    if (cost == 0.0LF) cost = 0.0LF;  // -0 and +0 are one cost, as for the CPU's ==
    uvec2 bits = unpackDouble2x32(cost);  // x: low word, y: high word
    bool negative = (bits.y & 0x80000000u) != 0u;
    uint high = negative ? ~bits.y : (bits.y | 0x80000000u);
    uint low = negative ? ~bits.x : bits.x;
    edge_keys[2u * i] = high;
    edge_keys[2u * i + 1u] = low;
    OfferHigh(a, high);
    if (kBothEnds) OfferHigh(b, high);
    return;
  }
  uint high = edge_keys[2u * i];
  uint low = edge_keys[2u * i + 1u];
  if (u_phase == 1u) {
    OfferLow(a, high, low);
    if (kBothEnds) OfferLow(b, high, low);
  } else {
    OfferPartner(a, b, high, low);
    if (kBothEnds) OfferPartner(b, a, high, low);
  }
}
