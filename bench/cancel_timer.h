// For the benches' --cancel-after S: sets a cancel flag S seconds after construction, on its
// own thread, and reports how long the cancelled call took to return after the flag.
#ifndef MLCLUST_BENCH_CANCEL_TIMER_H_
#define MLCLUST_BENCH_CANCEL_TIMER_H_

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <mutex>
#include <thread>

#include "absl/status/status.h"
#include "absl/time/clock.h"

namespace mlclust::bench {

class CancelTimer {
 public:
  // after_seconds < 0: never sets the flag (flag() is null).
  explicit CancelTimer(double after_seconds) : after_(after_seconds), start_(absl::Now()) {
    if (after_ < 0) return;
    thread_ = std::thread([this] {
      std::unique_lock<std::mutex> lock(mutex_);
      if (wake_.wait_for(lock, std::chrono::duration<double>(after_), [this] { return done_; })) {
        return;  // the call ended first
      }
      set_at_ = absl::Now();
      flag_ = true;
    });
  }
  ~CancelTimer() { Stop(); }

  const std::atomic<bool>* flag() const { return after_ < 0 ? nullptr : &flag_; }

  // Call as soon as the cancellable call returns: prints to stderr when the flag was set
  // and how long after it the call returned, with the call's status.
  void Report(const absl::Status& status, const char* what) {
    const absl::Time returned = absl::Now();
    Stop();
    if (after_ < 0) return;
    if (!flag_) {
      std::fprintf(stderr, "cancel: %s ended after %.3f s, before the flag\n", what,
                   absl::ToDoubleSeconds(returned - start_));
      return;
    }
    std::fprintf(stderr, "cancel: %s returned %.4f s after the flag (set at %.3f s): %s\n", what,
                 absl::ToDoubleSeconds(returned - set_at_), absl::ToDoubleSeconds(set_at_ - start_),
                 status.ToString().c_str());
  }

 private:
  void Stop() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      done_ = true;
    }
    wake_.notify_all();
    if (thread_.joinable()) thread_.join();
  }

  const double after_;
  const absl::Time start_;
  absl::Time set_at_;
  std::atomic<bool> flag_{false};
  std::mutex mutex_;
  std::condition_variable wake_;
  bool done_ = false;
  std::thread thread_;
};

}  // namespace mlclust::bench

#endif  // MLCLUST_BENCH_CANCEL_TIMER_H_
