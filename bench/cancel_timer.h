// For the benches' --cancel-after S and bench/cancel_latency: sets a cancel flag S seconds
// after construction, on its own thread, and says how long the cancelled call took to
// return after the flag.
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

  struct Outcome {
    bool flag_set = false;
    double returned_s = 0;  // from construction to Finish
    double set_at_s = 0;    // from construction to the flag (flag_set only)
    double latency_s = 0;   // from the flag to Finish (flag_set only)
  };

  // Call as soon as the cancellable call returns: stops the timer (the flag is never set
  // after this) and says whether and when the flag was set, and how long after it the call
  // returned.
  Outcome Finish() {
    const absl::Time returned = absl::Now();
    Stop();
    Outcome outcome;
    outcome.returned_s = absl::ToDoubleSeconds(returned - start_);
    if (!flag_) return outcome;
    outcome.flag_set = true;
    outcome.set_at_s = absl::ToDoubleSeconds(set_at_ - start_);
    outcome.latency_s = absl::ToDoubleSeconds(returned - set_at_);
    return outcome;
  }

  // Finish, then prints to stderr when the flag was set and how long after it the call
  // returned, with the call's status (nothing when the timer never sets the flag).
  void Report(const absl::Status& status, const char* what) {
    const Outcome outcome = Finish();
    if (after_ < 0) return;
    if (!outcome.flag_set) {
      std::fprintf(stderr, "cancel: %s ended after %.3f s, before the flag\n", what,
                   outcome.returned_s);
      return;
    }
    std::fprintf(stderr, "cancel: %s returned %.4f s after the flag (set at %.3f s): %s\n", what,
                 outcome.latency_s, outcome.set_at_s, status.ToString().c_str());
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
