// PML on the GPU, shared by the mesh (pml_pairs.glsl) and point (points_pairs.glsl)
// levels: the mutual pairs of optimal dual edges (Alg. 5.8), each found once from its
// smaller cluster c (c < partner(c), partner(partner(c)) = c, as the CPU engine's
// FindMutualPairs), appended with its merge cost (c's sums first) at a slot from an atomic
// counter (their order is not used: the level's merges are disjoint). One invocation per
// cluster id. After the engine's part, which defines ClusterIsEmpty(c) and
// PairMergeCost(c, d).
layout(std430, binding = 7) readonly buffer Odes { uint odes[]; };
layout(std430, binding = 8) writeonly buffer PairIds { uint pair_ids[]; };          // (c, d)
layout(std430, binding = 9) writeonly buffer PairValues { double pair_values[]; };  // 3 per pair
layout(std430, binding = 13) buffer Counters { uint counters[]; };
layout(location = 0) uniform uint u_count;  // cluster ids

void main() {
  uint c = LinearInvocationIndex();
  if (c >= u_count || ClusterIsEmpty(c)) return;
  uint partner = odes[3u * c + 2u];
  if (partner == 0u) return;
  uint d = partner - 1u;
  if (c >= d || odes[3u * d + 2u] != c + 1u) return;
  uint slot = atomicAdd(counters[0], 1u);
  pair_ids[2u * slot] = c;
  pair_ids[2u * slot + 1u] = d;
  pair_values[3u * slot] = PairMergeCost(c, d);
}
