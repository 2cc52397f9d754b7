// ML/PML for points on the GPU (points_levels.h): the host's LN k-means moves written into
// the resident state (PointLevelsGpu::Update), one invocation per entry: first the changed
// clusters (count, sums, centroid), then the moved points (label). After
// points_common.glsl.
layout(std430, binding = 2) writeonly buffer Labels { uint labels[]; };
layout(std430, binding = 6) writeonly buffer Sums { double sums[]; };  // k x (d + 1)
// u_clusters cluster ids, their counts, then u_points point ids and their labels.
layout(std430, binding = 8) readonly buffer UpdateIds { uint update_ids[]; };
// Per changed cluster: its d + 1 sums, then its d centroid values.
layout(std430, binding = 9) readonly buffer UpdateValues { double update_values[]; };
layout(location = 0) uniform uint u_clusters;
layout(location = 1) uniform uint u_points;

void main() {
  uint r = LinearInvocationIndex();
  if (r < u_clusters) {
    uint c = update_ids[r];
    counts[c] = update_ids[u_clusters + r];
    uint stride = 2u * u_dims + 1u;
    for (uint j = 0u; j <= u_dims; ++j) sums[c * (u_dims + 1u) + j] = update_values[r * stride + j];
    for (uint j = 0u; j < u_dims; ++j) {
      centroids[c * u_dims + j] = update_values[r * stride + u_dims + 1u + j];
    }
  } else if (r < u_clusters + u_points) {
    uint p = r - u_clusters;
    labels[update_ids[2u * u_clusters + p]] = update_ids[2u * u_clusters + u_points + p];
  }
}
