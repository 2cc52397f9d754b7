// PML on the GPU (pml_levels.h): the collapse of the level's pairs (Alg. 5.8), one
// invocation per pair: the larger cluster keeps its id, the smaller id on equal sizes
// (the CPU engine's KeepAndGone); the kept cluster's sums become keep + gone in the
// CPU's order (CvdSums::operator+=), the gone cluster's are zeroed and it maps to the
// kept one (remap) for the relabelling passes. The energy changes of both clusters
// (E after - E before, as the CPU's LevelRecorder takes them) go to pair_values[3i + 1,
// 3i + 2]. With u_use_flags, only the pairs whose flag is set merge. After pml_cvd.glsl.
layout(std430, binding = 1) buffer Sizes { uint sizes[]; };
layout(std430, binding = 3) buffer Remap { uint remap[]; };
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
  uint size_a = sizes[a];
  uint size_b = sizes[b];
  bool a_keeps = size_a > size_b || (size_a == size_b && a < b);
  uint keep = a_keeps ? a : b;
  uint gone = a_keeps ? b : a;
  precise double keep_before = CvdEnergy(keep);
  precise double gone_before = CvdEnergy(gone);
  for (uint j = 0u; j < 5u; ++j) {
    precise double sum = sums[5u * keep + j] + sums[5u * gone + j];
    sums[5u * keep + j] = sum;
    sums[5u * gone + j] = 0.0LF;
  }
  sizes[keep] = size_a + size_b;
  sizes[gone] = 0u;
  remap[gone] = keep;
  precise double keep_after = CvdEnergy(keep);
  pair_values[3u * i + 1u] = keep_after - keep_before;
  pair_values[3u * i + 2u] = 0.0LF - gone_before;
}
