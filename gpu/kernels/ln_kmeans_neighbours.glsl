// LnKmeansKernel::InitialNeighbours (ln_kmeans.h): the local neighbours of eq. 6.1 by
// brute force, one invocation per cluster: in each of the 2d half-axis subspaces
// (SubspaceIndex) the nearest other non-empty cluster, the smaller id on ties. O(k^2 d),
// the start of LN k-means from seeds. After the prelude of gpu/context/compute.h.
layout(std430, binding = 3) readonly buffer Centroids { double centroids[]; };  // d per cluster
layout(std430, binding = 4) writeonly buffer Neighbours { uint neighbours[]; };  // 2d per cluster
layout(std430, binding = 5) readonly buffer Counts { uint counts[]; };           // per cluster
layout(location = 0) uniform uint u_clusters;  // k
layout(location = 1) uniform uint u_dims;      // d (<= kMaxDims)
const uint kNone = 0xFFFFFFFFu;
const uint kMaxDims = 64u;

void main() {
  uint c = LinearInvocationIndex();
  if (c >= u_clusters) return;
  uint width = 2u * u_dims;
  double best[2u * kMaxDims];
  for (uint t = 0u; t < width; ++t) {
    neighbours[c * width + t] = kNone;
    best[t] = packDouble2x32(uvec2(0u, 0x7FF00000u));  // +infinity
  }
  if (counts[c] == 0u) return;
  for (uint n = 0u; n < u_clusters; ++n) {
    if (n == c || counts[n] == 0u) continue;
    uint axis = 0u;
    double largest = -1.0LF;
    precise double dist = 0.0LF;
    for (uint j = 0u; j < u_dims; ++j) {
      precise double diff = centroids[c * u_dims + j] - centroids[n * u_dims + j];
      double spread = abs(centroids[n * u_dims + j] - centroids[c * u_dims + j]);
      if (spread > largest) {
        largest = spread;
        axis = j;
      }
      dist += diff * diff;
    }
    uint s = 2u * axis + (centroids[n * u_dims + axis] > centroids[c * u_dims + axis] ? 0u : 1u);
    if (dist < best[s]) {
      best[s] = dist;
      neighbours[c * width + s] = n;
    }
  }
}
