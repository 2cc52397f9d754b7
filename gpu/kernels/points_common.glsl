// ML/PML for points on the GPU (points_levels.h): the clusters' sizes and centroids and
// the variance energy's merge cost, shared by the point level kernels (after the prelude
// of gpu/context/compute.h, before the kernel). Every intermediate is `precise` (no fused
// multiply-add) and in the CPU's operation order (WardMergeCost, EnergyOfSums and
// SubspaceIndex of core/energy/variance_energy.h and core/cluster/point_clustering.h), so
// on IEEE fp64 hardware the costs are the CPU's bit for bit.
layout(std430, binding = 0) buffer Counts { uint counts[]; };
layout(std430, binding = 1) buffer Centroids { double centroids[]; };  // k x d
layout(location = 2) uniform uint u_dims;
const uint kNone = 0xFFFFFFFFu;

// WardMergeCost(n_a, c_a, n_b, c_b): (n_a n_b / (n_a + n_b)) |c_a - c_b|^2.
double WardCost(uint a, uint b) {
  if (counts[a] == 0u || counts[b] == 0u) return 0.0LF;
  precise double na = double(counts[a]);
  precise double nb = double(counts[b]);
  precise double distance = 0.0LF;
  for (uint j = 0u; j < u_dims; ++j) {
    precise double diff = centroids[a * u_dims + j] - centroids[b * u_dims + j];
    distance += diff * diff;
  }
  precise double cost = na * nb / (na + nb) * distance;
  return cost;
}

// |c_a - c_b|^2 in the order of PointClusters::RefreshNeighbours.
double CentroidDistance(uint a, uint b) {
  precise double distance = 0.0LF;
  for (uint j = 0u; j < u_dims; ++j) {
    precise double diff = centroids[a * u_dims + j] - centroids[b * u_dims + j];
    distance += diff * diff;
  }
  return distance;
}

// SubspaceIndex(centroid of from, centroid of to): the axis of the largest difference
// (ties to the lower axis), 2j where to is above, 2j + 1 otherwise.
uint Subspace(uint from, uint to) {
  uint axis = 0u;
  double largest = -1.0LF;
  for (uint j = 0u; j < u_dims; ++j) {
    double diff = abs(centroids[to * u_dims + j] - centroids[from * u_dims + j]);
    if (diff > largest) {
      largest = diff;
      axis = j;
    }
  }
  return 2u * axis + (centroids[to * u_dims + axis] > centroids[from * u_dims + axis] ? 0u : 1u);
}
