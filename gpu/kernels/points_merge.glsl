// ML/PML for points on the GPU (points_levels.h): the collapse of the level's pairs, one
// invocation per pair. The larger cluster keeps its id, the smaller id on equal sizes
// (the CPU engine's KeepAndGone); the kept cluster's sums become keep + gone (count,
// square, then the coordinate sums: PointClusters::MergeSums) and its centroid sum / n;
// the gone cluster's are zeroed, it maps to the kept one (remap) for the relabelling
// and the kept one remembers it for the neighbour refresh (partner: gone, level). The
// energy changes of both (E after - E before, EnergyOfSums) go to pair_values[3i + 1,
// 3i + 2]. With u_use_flags only the pairs whose flag is set merge. After
// points_common.glsl.
layout(std430, binding = 3) buffer Remap { uint remap[]; };
layout(std430, binding = 6) buffer Sums { double sums[]; };  // k x (d + 1): sum, square
layout(std430, binding = 8) readonly buffer PairIds { uint pair_ids[]; };
layout(std430, binding = 9) buffer PairValues { double pair_values[]; };
layout(std430, binding = 10) readonly buffer PairSelected { uint pair_selected[]; };
layout(std430, binding = 15) buffer Partner { uint partner[]; };  // (gone, level) per cluster
layout(location = 0) uniform uint u_count;  // pairs
layout(location = 1) uniform uint u_use_flags;
layout(location = 3) uniform uint u_level;

// EnergyOfSums(n, sum, square): max(0, square - |sum|^2 / n); 0 for no points.
double Energy(uint c) {
  if (counts[c] == 0u) return 0.0LF;
  uint stride = u_dims + 1u;
  precise double s2 = 0.0LF;
  for (uint j = 0u; j < u_dims; ++j) {
    precise double s = sums[c * stride + j];
    s2 += s * s;
  }
  precise double energy = sums[c * stride + u_dims] - s2 / double(counts[c]);
  return max(0.0LF, energy);
}

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
  uint size_a = counts[a];
  uint size_b = counts[b];
  bool a_keeps = size_a > size_b || (size_a == size_b && a < b);
  uint keep = a_keeps ? a : b;
  uint gone = a_keeps ? b : a;
  precise double keep_before = Energy(keep);
  precise double gone_before = Energy(gone);
  uint stride = u_dims + 1u;
  precise double square = sums[keep * stride + u_dims] + sums[gone * stride + u_dims];
  sums[keep * stride + u_dims] = square;
  sums[gone * stride + u_dims] = 0.0LF;
  counts[keep] = size_a + size_b;
  counts[gone] = 0u;
  precise double n = double(size_a + size_b);
  for (uint j = 0u; j < u_dims; ++j) {
    precise double sum = sums[keep * stride + j] + sums[gone * stride + j];
    sums[keep * stride + j] = sum;
    sums[gone * stride + j] = 0.0LF;
    precise double mean = sum / n;
    centroids[keep * u_dims + j] = mean;
  }
  remap[gone] = keep;
  partner[2u * keep] = gone;
  partner[2u * keep + 1u] = u_level;
  precise double keep_after = Energy(keep);
  pair_values[3u * i + 1u] = keep_after - keep_before;
  pair_values[3u * i + 2u] = 0.0LF - gone_before;
}
