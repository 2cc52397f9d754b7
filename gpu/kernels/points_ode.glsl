// ML/PML for points on the GPU (points_levels.h): every cluster's optimal dual edge over
// its local neighbours and the clusters that list it as theirs (the CPU's
// ForEachCandidate: the dual edges are symmetric), the cheapest Ward cost, equal costs to
// the larger id (CheaperDualEdge). One invocation per neighbour slot (cluster c, slot s);
// each edge (c, n) offers itself to both ends. Without 64-bit atomics the minimum of a
// double is taken in three 32-bit passes on an order-preserving key of its bits (exact),
// as pml_ode.glsl:
//   phase 3 (per cluster)  reset: key (~0, ~0), partner none (0)
//   phase 0 (per slot)     cost, its key; atomicMin of the key's high word at both ends
//   phase 1 (per slot)     where the high word is an end's minimum: atomicMin of the low
//   phase 2 (per slot)     where the whole key is an end's minimum: atomicMax of the other
//                          end + 1
// After points_common.glsl.
layout(std430, binding = 4) readonly buffer Neighbours { uint neighbours[]; };  // k x 2d
layout(std430, binding = 7) buffer Odes { uint odes[]; };  // (high, low, partner + 1)
layout(std430, binding = 16) buffer EdgeKeys { uint edge_keys[]; };  // (high, low) per slot
layout(location = 0) uniform uint u_count;  // slots (phases 0-2) or clusters (phase 3)
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
  uint a = i / (2u * u_dims);
  uint b = neighbours[i];
  if (b == kNone || counts[a] == 0u || counts[b] == 0u) return;
  if (u_phase == 0u) {
    double cost = WardCost(a, b);
    if (cost == 0.0LF) cost = 0.0LF;  // -0 and +0 are one cost
    uvec2 bits = unpackDouble2x32(cost);
    bool negative = (bits.y & 0x80000000u) != 0u;
    uint high = negative ? ~bits.y : (bits.y | 0x80000000u);
    uint low = negative ? ~bits.x : bits.x;
    edge_keys[2u * i] = high;
    edge_keys[2u * i + 1u] = low;
    atomicMin(odes[3u * a], high);
    atomicMin(odes[3u * b], high);
  } else if (u_phase == 1u) {
    uint high = edge_keys[2u * i];
    uint low = edge_keys[2u * i + 1u];
    if (high == odes[3u * a]) atomicMin(odes[3u * a + 1u], low);
    if (high == odes[3u * b]) atomicMin(odes[3u * b + 1u], low);
  } else {
    uint high = edge_keys[2u * i];
    uint low = edge_keys[2u * i + 1u];
    if (high == odes[3u * a] && low == odes[3u * a + 1u]) atomicMax(odes[3u * a + 2u], b + 1u);
    if (high == odes[3u * b] && low == odes[3u * b + 1u]) atomicMax(odes[3u * b + 2u], a + 1u);
  }
}
