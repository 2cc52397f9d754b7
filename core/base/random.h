// Reproducible random numbers: the same seed gives the same sequence on every platform
// (std::uniform_int_distribution is implementation-defined, so it is not used).
#ifndef MLCLUST_CORE_BASE_RANDOM_H_
#define MLCLUST_CORE_BASE_RANDOM_H_

#include <cstdint>
#include <random>

namespace mlclust {

class Random {
 public:
  explicit Random(uint64_t seed) : engine_(seed) {}

  // Uniform in [0, bound), bound >= 1, by rejection (no modulo bias).
  uint64_t Below(uint64_t bound) {
    const uint64_t limit = UINT64_MAX - UINT64_MAX % bound;
    uint64_t x;
    do {
      x = engine_();
    } while (x >= limit);
    return x % bound;
  }
  // Uniform in [0, 1).
  double Unit() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; }
  uint64_t Next() { return engine_(); }

 private:
  std::mt19937_64 engine_;
};

}  // namespace mlclust

#endif  // MLCLUST_CORE_BASE_RANDOM_H_
