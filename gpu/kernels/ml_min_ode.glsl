// ML (Alg. 5.6) on the GPU (pml_levels.h, PmlLevelsGpu::Step): findMinDE(), the cheapest
// optimal dual edge of all clusters, after pml_ode.glsl found every cluster's ODE (its key
// and partner + 1, binding 7). The order is the CPU engine's queue's (OdeHeap, and HC's
// tree of minima, hc_common.glsl's Before): cheaper first, then the smaller tie key (the
// cluster's size with u_tie_by_size, else none), then the smaller id. The key is the
// cost's bits made order-preserving (pml_ode.glsl), so (high, low) compare as the costs.
// One work group: each invocation walks every 256th cluster (u_count / 256 loop iterations,
// within llvmpipe's 65,535 up to 16.7 million clusters), then a reduction in shared memory.
// Writes the winner and its partner as pair 0 (pair_ids[0], pair_ids[1]) for pml_merge.glsl,
// or kNone twice where no cluster has an ODE. After the prelude of gpu/context/compute.h.
layout(std430, binding = 1) readonly buffer Sizes { uint sizes[]; };
layout(std430, binding = 7) readonly buffer Odes { uint odes[]; };
layout(std430, binding = 8) writeonly buffer PairIds { uint pair_ids[]; };
layout(location = 0) uniform uint u_count;  // cluster ids
layout(location = 1) uniform uint u_tie_by_size;
const uint kNone = 0xFFFFFFFFu;
const uint kGroup = 256u;  // the prelude's local_size_x
shared uvec4 s_best[kGroup];  // (key high, key low, tie key, cluster), cluster kNone: none

bool Before(uvec4 x, uvec4 y) {
  if (x.w == kNone) return false;
  if (y.w == kNone) return true;
  if (x.x != y.x) return x.x < y.x;
  if (x.y != y.y) return x.y < y.y;
  if (x.z != y.z) return x.z < y.z;
  return x.w < y.w;
}

void main() {
  uint t = gl_LocalInvocationID.x;
  uvec4 best = uvec4(0u, 0u, 0u, kNone);
  for (uint c = t; c < u_count; c += kGroup) {
    if (sizes[c] == 0u || odes[3u * c + 2u] == 0u) continue;
    uvec4 mine = uvec4(odes[3u * c], odes[3u * c + 1u], u_tie_by_size != 0u ? sizes[c] : 0u, c);
    if (Before(mine, best)) best = mine;
  }
  s_best[t] = best;
  memoryBarrierShared();
  barrier();
  for (uint half_size = kGroup / 2u; half_size > 0u; half_size >>= 1u) {
    if (t < half_size && Before(s_best[t + half_size], s_best[t])) s_best[t] = s_best[t + half_size];
    memoryBarrierShared();
    barrier();
  }
  if (t == 0u) {
    uint winner = s_best[0].w;
    pair_ids[0] = winner;
    pair_ids[1] = winner == kNone ? kNone : odes[3u * winner + 2u] - 1u;
  }
}
