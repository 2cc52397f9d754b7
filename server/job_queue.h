// A bounded FIFO of jobs that refuses at once when full, with lanes: each job waits in one
// lane (which workers may take it) and workers take the oldest job of the lanes they
// serve. The capacity is shared by all lanes.
//
// Ownership: Push takes the job (shared with the submitting call, which keeps a handle to
// cancel it); Pop hands it to a worker; Remove takes a queued job out again (a cancelled
// call frees its input at once instead of when a worker reaches it); TakeAll empties the
// queue (drain) and hands every waiting job back to the caller.
#ifndef MLCLUST_SERVER_JOB_QUEUE_H_
#define MLCLUST_SERVER_JOB_QUEUE_H_

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"

namespace mlclust::server {

template <typename Job>
class BoundedJobQueue {
 public:
  // Lanes are numbered 0..31; a worker serves a bit mask of them.
  static constexpr unsigned kAllLanes = ~0u;

  explicit BoundedJobQueue(size_t capacity) : capacity_(capacity) {}

  // `on_full(full)` is called with true when the queue becomes full (`capacity` jobs
  // waiting: the next Push is refused) and with false when it has room again, under the
  // queue's lock (keep it short, never call back into the queue). The server's readiness
  // follows it (server.cc). Set before the queue is used.
  void SetOnFull(std::function<void(bool full)> on_full) { on_full_ = std::move(on_full); }

  // Appends `job` to `lane` and returns the number of jobs ahead of it in that lane.
  // RESOURCE_EXHAUSTED at once when `capacity` jobs are waiting; FAILED_PRECONDITION once
  // the queue is stopped. `on_queued(jobs_ahead)` runs before any Pop can return the job
  // (under the queue's lock: keep it short, never call back into the queue).
  template <typename OnQueued>
  absl::StatusOr<size_t> Push(std::shared_ptr<Job> job, unsigned lane, OnQueued on_queued) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (stopped_) return absl::FailedPreconditionError("the server is shutting down");
    if (jobs_.size() >= capacity_) {
      return absl::ResourceExhaustedError(
          absl::StrCat("the job queue is full (", capacity_, " jobs waiting); try again later"));
    }
    const size_t ahead = CountInLanes(1u << lane);
    on_queued(ahead);
    jobs_.push_back({lane, std::move(job)});
    NoteFullness();
    ready_.notify_all();
    return ahead;
  }
  absl::StatusOr<size_t> Push(std::shared_ptr<Job> job, unsigned lane = 0) {
    return Push(std::move(job), lane, [](size_t) {});
  }

  // Blocks until a job of one of `lanes` (a bit mask) is available and returns it, or
  // nullptr once stopped and no such job is left.
  std::shared_ptr<Job> Pop(unsigned lanes = kAllLanes) {
    std::unique_lock<std::mutex> lock(mutex_);
    while (true) {
      for (auto it = jobs_.begin(); it != jobs_.end(); ++it) {
        if ((lanes >> it->lane) & 1u) {
          std::shared_ptr<Job> job = std::move(it->job);
          jobs_.erase(it);
          NoteFullness();
          return job;
        }
      }
      if (stopped_) return nullptr;
      ready_.wait(lock);
    }
  }

  // Removes `job` if it is still waiting. Returns whether it was.
  bool Remove(const Job* job) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (auto it = jobs_.begin(); it != jobs_.end(); ++it) {
      if (it->job.get() == job) {
        jobs_.erase(it);
        NoteFullness();
        return true;
      }
    }
    return false;
  }

  // Calls visit(job, jobs_ahead_in_its_lane) for every waiting job, in order, under the
  // queue's lock (keep it short, never call back into the queue).
  template <typename Visit>
  void ForEachWaiting(Visit visit) const {
    std::lock_guard<std::mutex> lock(mutex_);
    size_t ahead[32] = {};
    for (const Entry& entry : jobs_) visit(*entry.job, ahead[entry.lane]++);
  }

  // Refuses new jobs; Pop drains what is queued and then returns nullptr.
  void Stop() {
    std::lock_guard<std::mutex> lock(mutex_);
    stopped_ = true;
    ready_.notify_all();
  }

  // Stops the queue and returns every waiting job (Pop then returns nullptr at once).
  std::vector<std::shared_ptr<Job>> StopAndTakeAll() {
    std::lock_guard<std::mutex> lock(mutex_);
    stopped_ = true;
    std::vector<std::shared_ptr<Job>> taken;
    for (Entry& entry : jobs_) taken.push_back(std::move(entry.job));
    jobs_.clear();
    NoteFullness();
    ready_.notify_all();
    return taken;
  }

  size_t size() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return jobs_.size();
  }
  size_t capacity() const { return capacity_; }

 private:
  struct Entry {
    unsigned lane;
    std::shared_ptr<Job> job;
  };

  // Under the lock: on_full_ when the queue became full or has room again.
  void NoteFullness() {
    const bool full = jobs_.size() >= capacity_;
    if (full == full_) return;
    full_ = full;
    if (on_full_) on_full_(full);
  }

  size_t CountInLanes(unsigned lanes) const {
    size_t n = 0;
    for (const Entry& entry : jobs_) n += (lanes >> entry.lane) & 1u;
    return n;
  }

  const size_t capacity_;
  mutable std::mutex mutex_;
  std::condition_variable ready_;
  std::deque<Entry> jobs_;
  bool stopped_ = false;
  bool full_ = false;
  std::function<void(bool)> on_full_;
};

}  // namespace mlclust::server

#endif  // MLCLUST_SERVER_JOB_QUEUE_H_
