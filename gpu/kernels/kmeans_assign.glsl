// KmeansAssignKernel::Assign (kmeans_assign.h): brute-force k-means assignment (section
// 6.4.4), one invocation per point: the nearest of the k centres by squared distance in
// fp32, the smaller index on ties. After the prelude of gpu/context/compute.h.
layout(std430, binding = 0) readonly buffer Points { float points[]; };    // d per point
layout(std430, binding = 1) readonly buffer Centres { float centres[]; };  // d per centre
layout(std430, binding = 2) writeonly buffer Labels { uint labels[]; };    // per point
layout(location = 0) uniform uint u_points;   // m
layout(location = 1) uniform uint u_dims;     // d
layout(location = 2) uniform uint u_centres;  // k

void main() {
  uint point = LinearInvocationIndex();
  if (point >= u_points) return;
  uint first = point * u_dims;
  float best = 0.0;
  uint best_centre = 0u;
  for (uint c = 0u; c < u_centres; ++c) {
    float dist = 0.0;
    for (uint j = 0u; j < u_dims; ++j) {
      float diff = points[first + j] - centres[c * u_dims + j];
      dist += diff * diff;
    }
    if (c == 0u || dist < best) {
      best = dist;
      best_centre = c;
    }
  }
  labels[point] = best_centre;
}
