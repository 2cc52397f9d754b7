// Kahan summation: keeps a running energy, a sum of up to millions of small changes,
// accurate to a few units in the last place.
#ifndef MLCLUST_CORE_BASE_COMPENSATED_SUM_H_
#define MLCLUST_CORE_BASE_COMPENSATED_SUM_H_

namespace mlclust::detail {

class CompensatedSum {
 public:
  void Add(double x) {
    const double y = x - compensation_;
    const double t = sum_ + y;
    compensation_ = (t - sum_) - y;
    sum_ = t;
  }
  void Reset(double value) {
    sum_ = value;
    compensation_ = 0;
  }
  double value() const { return sum_; }

 private:
  double sum_ = 0, compensation_ = 0;
};

}  // namespace mlclust::detail

#endif  // MLCLUST_CORE_BASE_COMPENSATED_SUM_H_
