// PML with boundary-based optimisation on the GPU (pml_levels.h, Alg. 5.7): the small
// passes around the BB decide kernel (bb_decide.glsl), on the PML's own buffers:
//   u_phase 0 (per cluster id)  fit the proxies: the centroid of the cluster's sums
//                               (CvdEnergy::FitProxy: weighted centroid * (1 / area), in
//                               the CPU's order) and weight 1, for bb_decide.glsl
//   u_phase 1 (per change)      write the moved faces' labels: labels[x] = y for (x, y)
//   u_phase 2 (per change)      write the changed clusters' sizes and sums (the host's
//                               Partition after its moves, so both hold the same bits),
//                               and fit their proxies again as phase 0 does
// After the prelude of gpu/context/compute.h and pml_cvd.glsl (Sums at binding 0).
layout(std430, binding = 1) buffer Sizes { uint sizes[]; };
layout(std430, binding = 2) buffer Labels { uint labels[]; };
layout(std430, binding = 3) writeonly buffer Proxies { dvec4 proxies[]; };
layout(std430, binding = 4) readonly buffer LabelChanges { uvec2 label_changes[]; };
layout(std430, binding = 5) readonly buffer ClusterChanges { uvec2 cluster_changes[]; };  // id, size
layout(std430, binding = 6) readonly buffer ClusterSums { double cluster_sums[]; };  // 5 per change
layout(location = 0) uniform uint u_count;
layout(location = 1) uniform uint u_phase;

void FitProxy(uint c) {
  precise double m = sums[5u * c];
  if (sizes[c] == 0u || m <= 0.0LF) {
    proxies[c] = dvec4(0.0LF, 0.0LF, 0.0LF, 1.0LF);
    return;
  }
  precise double inverse = 1.0LF / m;
  precise double x = sums[5u * c + 1u] * inverse;
  precise double y = sums[5u * c + 2u] * inverse;
  precise double z = sums[5u * c + 3u] * inverse;
  proxies[c] = dvec4(x, y, z, 1.0LF);
}

void main() {
  uint i = LinearInvocationIndex();
  if (i >= u_count) return;
  if (u_phase == 0u) {
    FitProxy(i);
  } else if (u_phase == 1u) {
    labels[label_changes[i].x] = label_changes[i].y;
  } else {
    uint c = cluster_changes[i].x;
    sizes[c] = cluster_changes[i].y;
    for (uint j = 0u; j < 5u; ++j) sums[5u * c + j] = cluster_sums[5u * i + j];
    FitProxy(c);
  }
}
