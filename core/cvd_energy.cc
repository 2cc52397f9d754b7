#include "core/cvd_energy.h"

#include <algorithm>

#include "absl/container/flat_hash_map.h"

namespace mlclust {

CvdSums CvdFaceSums(double area, const Vec3& centroid, const Vec3& origin) {
  const Vec3 g = centroid - origin;
  return {area, g * area, area * SquaredNorm(g)};
}

double CvdEnergy(const CvdSums& sums) {
  if (sums.area <= 0) return 0;
  return std::max(0.0,
                  sums.weighted_squared_norm - SquaredNorm(sums.weighted_centroid) / sums.area);
}

double CvdMergeCost(const CvdSums& a, const CvdSums& b) {
  if (a.area <= 0 || b.area <= 0) return 0;  // a zero-area cluster adds no energy
  const Vec3 difference = a.weighted_centroid / a.area - b.weighted_centroid / b.area;
  return a.area * b.area / (a.area + b.area) * SquaredNorm(difference);
}

double CvdEnergyDirect(const FaceMeasures& measures, std::span<const ClusterId> labels) {
  struct Accumulator {
    double area = 0;
    Vec3 weighted_centroid;
  };
  absl::flat_hash_map<ClusterId, Accumulator> clusters;
  for (size_t j = 0; j < labels.size(); ++j) {
    Accumulator& c = clusters[labels[j]];
    c.area += measures.area[j];
    c.weighted_centroid += measures.centroid[j] * measures.area[j];
  }
  double energy = 0;
  for (size_t j = 0; j < labels.size(); ++j) {
    const Accumulator& c = clusters[labels[j]];
    if (c.area <= 0) continue;
    energy += measures.area[j] * SquaredNorm(measures.centroid[j] - c.weighted_centroid / c.area);
  }
  return energy;
}

}  // namespace mlclust
