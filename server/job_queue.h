// A bounded FIFO of jobs that refuses at once when full.
//
// Ownership: Push takes the job (shared with the submitting call, which keeps a handle to
// cancel it); Pop hands it to the worker; Remove takes a queued job out again (a cancelled
// call frees its input at once instead of when the worker reaches it).
#ifndef MLCLUST_SERVER_JOB_QUEUE_H_
#define MLCLUST_SERVER_JOB_QUEUE_H_

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>

#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"

namespace mlclust::server {

template <typename Job>
class BoundedJobQueue {
 public:
  explicit BoundedJobQueue(size_t capacity) : capacity_(capacity) {}

  // Appends `job` and returns the number of jobs ahead of it. RESOURCE_EXHAUSTED at once
  // when `capacity` jobs are waiting; FAILED_PRECONDITION once the queue is stopped.
  // `on_queued(jobs_ahead)` runs before any Pop can return the job (under the queue's
  // lock: keep it short, never call back into the queue).
  template <typename OnQueued>
  absl::StatusOr<size_t> Push(std::shared_ptr<Job> job, OnQueued on_queued) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (stopped_) return absl::FailedPreconditionError("the server is shutting down");
    if (jobs_.size() >= capacity_) {
      return absl::ResourceExhaustedError(
          absl::StrCat("the job queue is full (", capacity_, " jobs waiting); try again later"));
    }
    const size_t ahead = jobs_.size();
    on_queued(ahead);
    jobs_.push_back(std::move(job));
    ready_.notify_one();
    return ahead;
  }
  absl::StatusOr<size_t> Push(std::shared_ptr<Job> job) {
    return Push(std::move(job), [](size_t) {});
  }

  // Blocks until a job is available and returns it, or nullptr once stopped and empty.
  std::shared_ptr<Job> Pop() {
    std::unique_lock<std::mutex> lock(mutex_);
    ready_.wait(lock, [&] { return stopped_ || !jobs_.empty(); });
    if (jobs_.empty()) return nullptr;
    std::shared_ptr<Job> job = std::move(jobs_.front());
    jobs_.pop_front();
    return job;
  }

  // Removes `job` if it is still waiting. Returns whether it was.
  bool Remove(const Job* job) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (auto it = jobs_.begin(); it != jobs_.end(); ++it) {
      if (it->get() == job) {
        jobs_.erase(it);
        return true;
      }
    }
    return false;
  }

  // Refuses new jobs; Pop drains what is queued and then returns nullptr.
  void Stop() {
    std::lock_guard<std::mutex> lock(mutex_);
    stopped_ = true;
    ready_.notify_all();
  }

  size_t size() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return jobs_.size();
  }
  size_t capacity() const { return capacity_; }

 private:
  const size_t capacity_;
  mutable std::mutex mutex_;
  std::condition_variable ready_;
  std::deque<std::shared_ptr<Job>> jobs_;
  bool stopped_ = false;
};

}  // namespace mlclust::server

#endif  // MLCLUST_SERVER_JOB_QUEUE_H_
