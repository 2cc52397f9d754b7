// The points' energy (section 6.5, eq. 6.5): the within-cluster sum of squares
//   E = sum_i sum_{x in C_i} |x - c_i|^2,  c_i the mean of C_i,
// with the mesh energies' shape (core/energy/energies.h): additive Sums per element and
// cluster, Energy(sums) (the incremental form sum |x|^2 - |sum x|^2 / n), MergeCost (Ward's
// criterion, (n_a n_b / (n_a + n_b)) |c_a - c_b|^2 = E(a u b) - E(a) - E(b), eq. 4.1), and
// a Proxy (the mean) with the cost of one element against it, |x - c|^2.
//
// Coordinates are taken relative to the data's mean (`origin()`), so that the difference
// of large terms in the incremental form keeps its precision.
//
// The span-based functions (EnergyOfSums, WardMergeCost) are the arithmetic itself, for
// drivers that keep cluster sums in flat arrays (d is only known at run time); the class
// wraps them for the generic drivers and tests.
#ifndef MLCLUST_CORE_ENERGY_VARIANCE_ENERGY_H_
#define MLCLUST_CORE_ENERGY_VARIANCE_ENERGY_H_

#include <algorithm>
#include <cstdint>
#include <span>
#include <vector>

#include "core/points/points.h"

namespace mlclust {

// Eq. 6.5 from sums: sum |x|^2 - |sum x|^2 / n, clamped at 0 against rounding; 0 for an
// empty cluster.
inline double EnergyOfSums(double count, std::span<const double> sum, double square) {
  if (count == 0) return 0;
  double s2 = 0;
  for (double s : sum) s2 += s * s;
  return std::max(0.0, square - s2 / count);
}

// E(a u b) - E(a) - E(b) from the two clusters' sizes and means, in the form free of
// cancellation (Ward): (n_a n_b / (n_a + n_b)) |c_a - c_b|^2; 0 if either is empty.
inline double WardMergeCost(double count_a, std::span<const double> mean_a, double count_b,
                            std::span<const double> mean_b) {
  if (count_a == 0 || count_b == 0) return 0;
  double distance = 0;
  for (size_t j = 0; j < mean_a.size(); ++j) {
    const double diff = mean_a[j] - mean_b[j];
    distance += diff * diff;
  }
  return count_a * count_b / (count_a + count_b) * distance;
}

class VarianceEnergy {
 public:
  struct Sums {
    double count = 0;
    std::vector<double> sum;  // sum x (relative to origin()); empty reads as zeros
    double square = 0;        // sum |x|^2

    Sums& operator+=(const Sums& o) {
      Grow(o.sum.size());
      count += o.count;
      for (size_t j = 0; j < o.sum.size(); ++j) sum[j] += o.sum[j];
      square += o.square;
      return *this;
    }
    Sums& operator-=(const Sums& o) {
      Grow(o.sum.size());
      count -= o.count;
      for (size_t j = 0; j < o.sum.size(); ++j) sum[j] -= o.sum[j];
      square -= o.square;
      return *this;
    }
    friend Sums operator+(Sums a, const Sums& b) { return a += b; }

   private:
    void Grow(size_t d) {
      if (sum.size() < d) sum.resize(d, 0.0);
    }
  };
  using Proxy = std::vector<double>;  // the cluster's mean, relative to origin()

  // `points` must outlive the energy (ValidatePoints first: finite values, d > 0).
  explicit VarianceEnergy(const PointSet& points) : points_(&points), origin_(points.dims, 0.0) {
    const size_t m = points.num_points();
    for (size_t i = 0; i < m; ++i) {
      for (uint32_t j = 0; j < points.dims; ++j) origin_[j] += points.values[i * points.dims + j];
    }
    for (double& o : origin_) o /= static_cast<double>(std::max<size_t>(m, 1));
  }

  uint32_t dims() const { return points_->dims; }
  size_t num_elements() const { return points_->num_points(); }
  const std::vector<double>& origin() const { return origin_; }

  // The sums of point i alone.
  Sums element_sums(uint32_t i) const {
    Sums sums;
    sums.count = 1;
    sums.sum.resize(dims());
    for (uint32_t j = 0; j < dims(); ++j) {
      const double v = points_->values[size_t{i} * dims() + j] - origin_[j];
      sums.sum[j] = v;
      sums.square += v * v;
    }
    return sums;
  }
  // The name the mesh drivers' generic code uses (Partition, EnergyFromSums).
  Sums face_sums(uint32_t i) const { return element_sums(i); }

  double Energy(const Sums& sums) const { return EnergyOfSums(sums.count, sums.sum, sums.square); }
  double MergeCost(const Sums& a, const Sums& b) const {
    return WardMergeCost(a.count, FitProxy(a), b.count, FitProxy(b));
  }
  Proxy FitProxy(const Sums& sums) const {
    Proxy mean(dims(), 0.0);
    if (sums.count == 0) return mean;
    for (size_t j = 0; j < sums.sum.size() && j < mean.size(); ++j) {
      mean[j] = sums.sum[j] / sums.count;
    }
    return mean;
  }
  // |x_i - c|^2: point i's term of eq. 6.5 against mean c (relative to origin()).
  double ElementCost(uint32_t i, const Proxy& proxy) const {
    double distance = 0;
    for (uint32_t j = 0; j < dims(); ++j) {
      const double diff = (points_->values[size_t{i} * dims() + j] - origin_[j]) - proxy[j];
      distance += diff * diff;
    }
    return distance;
  }
  double FaceCost(uint32_t i, const Proxy& proxy) const { return ElementCost(i, proxy); }

 private:
  const PointSet* points_;
  std::vector<double> origin_;
};

}  // namespace mlclust

#endif  // MLCLUST_CORE_ENERGY_VARIANCE_ENERGY_H_
