// PML on the GPU, shared by the mesh (pml_merge.glsl) and point (points_merge.glsl)
// levels: the collapse of the level's pairs (Alg. 5.8), one invocation per pair. The
// larger cluster keeps its id, the smaller id on equal sizes (the CPU engine's
// KeepAndGone); the energy changes of both clusters (E after - E before, as the CPU's
// LevelRecorder takes them) go to pair_values[3i + 1, 3i + 2]. With u_use_flags only the
// pairs whose flag is set merge (the others' changes are 0). After the engine's part,
// which defines ClusterSize(c), ClusterEnergy(c) and MergeInto(keep, gone, size): gone's
// data into keep's, keep's size becoming `size`.
layout(std430, binding = 8) readonly buffer PairIds { uint pair_ids[]; };
layout(std430, binding = 9) buffer PairValues { double pair_values[]; };
layout(std430, binding = 10) readonly buffer PairSelected { uint pair_selected[]; };
layout(location = 0) uniform uint u_count;  // pairs
layout(location = 1) uniform uint u_use_flags;

void main() {
  uint i = LinearInvocationIndex();
  if (i >= u_count) return;
  if (u_use_flags != 0u && pair_selected[i] == 0u) {
    pair_values[3u * i + 1u] = 0.0LF;
    pair_values[3u * i + 2u] = 0.0LF;
    return;
  }
  uint a = pair_ids[2u * i];
  uint b = pair_ids[2u * i + 1u];
  uint size_a = ClusterSize(a);
  uint size_b = ClusterSize(b);
  bool a_keeps = size_a > size_b || (size_a == size_b && a < b);
  uint keep = a_keeps ? a : b;
  uint gone = a_keeps ? b : a;
  precise double keep_before = ClusterEnergy(keep);
  precise double gone_before = ClusterEnergy(gone);
  MergeInto(keep, gone, size_a + size_b);
  precise double keep_after = ClusterEnergy(keep);
  pair_values[3u * i + 1u] = keep_after - keep_before;
  pair_values[3u * i + 2u] = 0.0LF - gone_before;
}
