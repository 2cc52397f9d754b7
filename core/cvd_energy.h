// The Centroidal Voronoi Diagram (CVD) energy with uniform density (section 3.1.3).
//
// For a clustering C_1..C_k of faces, E = sum_i sum_{j in C_i} A_j ||g_j - gbar_i||^2,
// with A_j and g_j the face's area and centroid and gbar_i the area-weighted centroid of
// cluster i. A cluster keeps three additive sums (eq. 3.7): sum A, sum A g, sum A |g|^2,
// and both its energy and the cost of merging two clusters follow from those sums alone.
#ifndef MLCLUST_CORE_CVD_ENERGY_H_
#define MLCLUST_CORE_CVD_ENERGY_H_

#include <span>
#include <vector>

#include "core/face_measures.h"
#include "core/ids.h"
#include "core/vec3.h"

namespace mlclust {

struct CvdSums {
  double area = 0;                   // sum A_j
  Vec3 weighted_centroid;            // sum A_j g_j
  double weighted_squared_norm = 0;  // sum A_j |g_j|^2

  CvdSums& operator+=(const CvdSums& o) {
    area += o.area;
    weighted_centroid += o.weighted_centroid;
    weighted_squared_norm += o.weighted_squared_norm;
    return *this;
  }
  friend CvdSums operator+(CvdSums a, const CvdSums& b) { return a += b; }
};

// The sums of a single face. `origin` is subtracted from the centroid first; energies are
// translation invariant, and a nearby origin (the mesh's centre) keeps the difference of
// large terms in CvdEnergy accurate.
CvdSums CvdFaceSums(double area, const Vec3& centroid, const Vec3& origin);

// Eq. 3.7: E = sum A|g|^2 - |sum A g|^2 / sum A, clamped at 0 against rounding.
double CvdEnergy(const CvdSums& sums);

// Eq. 4.3: E(A u B) - E(A) - E(B), from the sums only. Evaluated in the equivalent
// form (A_a A_b / (A_a + A_b)) |gbar_a - gbar_b|^2, which is never negative and loses no
// precision to cancellation (the same identity as Ward's criterion).
double CvdMergeCost(const CvdSums& a, const CvdSums& b);

// The energy by its definition, summed over faces in two passes (centroids first, then
// distances). For tests and for checking reported energies; `labels` has one entry per face.
double CvdEnergyDirect(const FaceMeasures& measures, std::span<const ClusterId> labels);

}  // namespace mlclust

#endif  // MLCLUST_CORE_CVD_ENERGY_H_
