// HC on the GPU (hc_levels.h): the start, after the prelude of gpu/context/compute.h,
// pml_cvd.glsl and hc_common.glsl.
//   u_phase 0 (per cluster)  the ODE that pml_ode.glsl found (its key and partner + 1,
//                            binding 7) as the cluster's partner and cost: the key is the
//                            cost's bits, order-preserving, so the cost comes back exact
//   u_phase 1 (per node)     the tree's level u_level from level u_level - 1, marks 0
layout(std430, binding = 7) readonly buffer Odes { uint odes[]; };  // pml_ode.glsl's
layout(location = 2) uniform uint u_phase;
layout(location = 3) uniform uint u_level;

void main() {
  uint i = LinearInvocationIndex();
  if (u_phase == 0u) {
    if (i >= u_clusters) return;
    uint partner = odes[3u * i + 2u];
    uint high = odes[3u * i];
    uint low = odes[3u * i + 1u];
    bool negative = (high & 0x80000000u) == 0u;
    uvec2 bits = negative ? uvec2(~low, ~high) : uvec2(low, high & 0x7FFFFFFFu);
    clusters[i].partner = partner == 0u ? kNone : partner - 1u;
    ode_cost[i] = partner == 0u ? packDouble2x32(uvec2(0u, 0x7FF00000u)) : packDouble2x32(bits);
    return;
  }
  if (i >= LevelSize(u_level)) return;
  RecomputeNode(u_level, i);
  tree[2u * (LevelOffset(u_level) + i) + 1u] = 0u;
}
