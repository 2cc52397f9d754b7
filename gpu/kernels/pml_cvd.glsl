// PML on the GPU (pml_levels.h): the CVD merge cost and energy of clusters, shared by the
// PML kernels (after the prelude of gpu/context/compute.h, before the kernel). The sums
// of cluster c are sums[5c .. 5c+4]: area, area * centroid (x, y, z), area * |centroid|^2
// (CvdSums). Every intermediate is `precise` (no contraction into fused multiply-adds), so
// the results are the CPU's bit for bit: the order of the operations is that of
// CvdMergeCost and CvdSumsEnergy in core/energy/energies.h (Vec3 / s multiplies by 1 / s).
layout(std430, binding = 0) buffer Sums { double sums[]; };

// CvdMergeCost(sums of a, sums of b): (m_a m_b / (m_a + m_b)) |gbar_a - gbar_b|^2.
double CvdMergeCost(uint a, uint b) {
  precise double ma = sums[5u * a];
  precise double mb = sums[5u * b];
  if (ma <= 0.0LF || mb <= 0.0LF) return 0.0LF;
  precise double ia = 1.0LF / ma;
  precise double ib = 1.0LF / mb;
  precise double dx = sums[5u * a + 1u] * ia - sums[5u * b + 1u] * ib;
  precise double dy = sums[5u * a + 2u] * ia - sums[5u * b + 2u] * ib;
  precise double dz = sums[5u * a + 3u] * ia - sums[5u * b + 3u] * ib;
  precise double squared = dx * dx + dy * dy + dz * dz;
  precise double cost = ma * mb / (ma + mb) * squared;
  return cost;
}

// CvdSumsEnergy(sums of c): max(0, sum m|g|^2 - |sum m g|^2 / sum m); 0 for no mass.
double CvdEnergy(uint c) {
  precise double m = sums[5u * c];
  if (m <= 0.0LF) return 0.0LF;
  precise double x = sums[5u * c + 1u];
  precise double y = sums[5u * c + 2u];
  precise double z = sums[5u * c + 3u];
  precise double dot = x * x + y * y + z * z;
  precise double energy = sums[5u * c + 4u] - dot / m;
  return max(0.0LF, energy);
}

// keep's sums become keep + gone in the CPU's order (CvdSums::operator+=), gone's zero: the
// collapse of a pair (pml_merge.glsl's MergeInto, hc_steps.glsl's Collapse).
void AddCvdSums(uint keep, uint gone) {
  for (uint j = 0u; j < 5u; ++j) {
    precise double sum = sums[5u * keep + j] + sums[5u * gone + j];
    sums[5u * keep + j] = sum;
    sums[5u * gone + j] = 0.0LF;
  }
}
