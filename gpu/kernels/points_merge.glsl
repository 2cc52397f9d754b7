// ML/PML for points on the GPU (points_levels.h): the points' part of the collapse of the
// level's pairs (pair_merge.glsl): the kept cluster's sums become keep + gone (count,
// square, then the coordinate sums: PointClusters::MergeSums) and its centroid sum / n;
// the gone cluster's are zeroed, it maps to the kept one (remap) for the relabelling
// and the kept one remembers it for the neighbour refresh (partner: gone, level). The
// energies are EnergyOfSums. After points_common.glsl, before pair_merge.glsl.
layout(std430, binding = 3) buffer Remap { uint remap[]; };
layout(std430, binding = 6) buffer Sums { double sums[]; };  // k x (d + 1): sum, square
layout(std430, binding = 15) buffer Partner { uint partner[]; };  // (gone, level) per cluster
layout(location = 3) uniform uint u_level;

uint ClusterSize(uint c) { return counts[c]; }

// EnergyOfSums(n, sum, square): max(0, square - |sum|^2 / n); 0 for no points.
double ClusterEnergy(uint c) {
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

void MergeInto(uint keep, uint gone, uint size) {
  uint stride = u_dims + 1u;
  precise double square = sums[keep * stride + u_dims] + sums[gone * stride + u_dims];
  sums[keep * stride + u_dims] = square;
  sums[gone * stride + u_dims] = 0.0LF;
  counts[keep] = size;
  counts[gone] = 0u;
  precise double n = double(size);
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
}
