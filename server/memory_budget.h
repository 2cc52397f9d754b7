// A byte budget shared by threads: reservations either fit under the limit or are refused
// whole, so a refusal can be answered before anything is allocated.
#ifndef MLCLUST_SERVER_MEMORY_BUDGET_H_
#define MLCLUST_SERVER_MEMORY_BUDGET_H_

#include <atomic>
#include <cstdint>

namespace mlclust::server {

class MemoryBudget {
 public:
  explicit MemoryBudget(uint64_t limit_bytes) : limit_(limit_bytes) {}
  MemoryBudget(const MemoryBudget&) = delete;
  MemoryBudget& operator=(const MemoryBudget&) = delete;

  // Reserves `bytes` if used() + bytes stays within the limit; otherwise reserves nothing
  // and returns false.
  bool TryReserve(uint64_t bytes) {
    uint64_t used = used_.load(std::memory_order_relaxed);
    do {
      if (bytes > limit_ || used > limit_ - bytes) return false;
    } while (!used_.compare_exchange_weak(used, used + bytes, std::memory_order_relaxed));
    return true;
  }
  // Returns `bytes` reserved earlier.
  void Release(uint64_t bytes) { used_.fetch_sub(bytes, std::memory_order_relaxed); }

  uint64_t used() const { return used_.load(std::memory_order_relaxed); }
  uint64_t limit() const { return limit_; }

 private:
  const uint64_t limit_;
  std::atomic<uint64_t> used_{0};
};

}  // namespace mlclust::server

#endif  // MLCLUST_SERVER_MEMORY_BUDGET_H_
