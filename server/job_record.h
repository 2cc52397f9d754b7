// What the server knows of each job after it is accepted, and the result store of every
// job: the levels Watch reads.
//
// Every accepted job gets a JobRecord in the server's JobRegistry: its state, tenant and
// sizes (ListJobs), the handle Cancel uses, and its levels. A detached job (JobSpec.detach)
// writes its events to its record only: the record is the job's EventChannel. An attached
// job writes them to its call and a copy to its record (RecordingChannel). Either way the
// record keeps the snapshot and the level batches (compactly: 4 bytes per label, 12 per
// triplet) and any number of watchers read them, each at its own pace, while the job runs
// or after it ended. Producing never waits on a watcher.
//
// Retention: an ended job's record stays for the registry's retention time; kept levels
// count against the registry's memory budget, and when a running job needs more, the
// oldest ended jobs' levels are dropped first (an attached job, whose caller has its levels,
// only drops other attached jobs' levels). A detached job that cannot fit even then is
// cancelled with RESOURCE_EXHAUSTED; an attached one runs on for its caller and only stops
// keeping (Watch then answers NOT_FOUND saying so). A dropped job leaves a short note, so
// Watch answers NOT_FOUND saying when and why.
//
// Lock order: the registry's mutex before a record's; a record never calls the registry
// while holding its own.
#ifndef MLCLUST_SERVER_JOB_RECORD_H_
#define MLCLUST_SERVER_JOB_RECORD_H_

#include <atomic>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/time/time.h"
#include "server/job.h"
#include "server/memory_budget.h"

namespace mlclust::server {

enum class JobState { kQueued, kRunning, kSucceeded, kFailed, kCancelled };

// "queued", "running", "succeeded", "failed", "cancelled".
const char* JobStateName(JobState state);

class JobRegistry;

// Woken (once) when a record it waits on has something new. Called without any record
// lock held.
class RecordWaiter {
 public:
  virtual ~RecordWaiter() = default;
  virtual void Wake() = 0;
};

// A watcher's position in a record (WatchRequest's from_level and resume, then how far it
// has read).
struct WatchCursor {
  enum class Phase { kHeader, kSnapshot, kLevels, kFinal, kEnded };
  Phase phase = Phase::kHeader;
  uint32_t from_level = 0;
  bool resume = false;
  bool snapshot_built = false;
  // The labels at from_level > 0 while the snapshot is sent, shared by every watcher of
  // that level (the record keeps one copy however many read it); level 0 is sent from
  // the record's own labels.
  std::shared_ptr<const std::vector<uint32_t>> labels;
  size_t snapshot_sent = 0;
  uint32_t next_level = 0;     // the next level to send
  uint64_t next_triplet = 0;   // within next_level, when a big level is split
  uint64_t progress_seen = 0;  // the last Progress sent
};

// A Watch call's cursor from its request (WatchRequest's from_level and resume): the
// snapshot at from_level then the levels after it, or with `resume` only the levels after
// it. No level comes after the largest level number (4294967295): resuming from it reads
// no level (next_level saturates; it once wrapped to level 0 and read before the levels).
WatchCursor WatchCursorFor(uint32_t from_level, bool resume);

class JobRecord : public EventChannel {
 public:
  // `detached`: a detached job, whose only channel is this record (see Keep for attached
  // ones). `max_event_bytes`: the largest event a watcher is sent (bigger snapshots and
  // levels are split).
  JobRecord(JobRegistry* registry, std::string id, std::string tenant, v1::JobSpec spec,
            bool detached, size_t max_event_bytes);
  ~JobRecord() override;

  // EventChannel: the worker's side, for a detached job.
  bool Emit(v1::JobEvent event) override;
  // Keeps a copy of an attached job's event (RecordingChannel). Never cancels the job: when
  // the levels do not fit the memory for kept results, the record stops keeping them.
  void Keep(const v1::JobEvent& event);
  void Finish(v1::JobEvent final_event, const grpc::Status& status) override;
  void Abort(const grpc::Status& status) override;
  bool cancelled() const override { return cancelled_.load(std::memory_order_relaxed); }
  const std::atomic<bool>* cancel_flag() const override { return &cancelled_; }

  // State, for every job.
  void set_job(std::weak_ptr<Job> job) { job_ = std::move(job); }
  // What the job's Accepted event said about its input (face ids, Draco method): a
  // watcher's first event repeats it. Call before the job is queued.
  void set_accepted(const v1::Accepted& accepted) { accepted_ = accepted; }
  std::shared_ptr<Job> job() const { return job_.lock(); }
  void MarkRunning();
  // The job ended (the first call counts): its status, and for a successful job its Done.
  void MarkEnded(const grpc::Status& status, const v1::Done* done = nullptr);
  bool ended() const { return ended_.load(std::memory_order_acquire); }
  JobState state() const;
  absl::Time ended_at() const;
  v1::JobSummary Summary(absl::Time now, absl::Duration retention) const;

  const std::string& id() const { return id_; }
  const v1::JobSpec& spec() const { return spec_; }
  const std::string& tenant() const { return tenant_; }
  // The connection that submitted the job (its peer string, "ipv4:127.0.0.1:41234"): without
  // tokens, ListJobs shows a caller only the jobs its own connection submitted. Set before
  // the record is added to the registry.
  void set_owner(std::string owner) { owner_ = std::move(owner); }
  const std::string& owner() const { return owner_; }
  bool detached() const { return detached_; }
  // The levels were dropped (retention, memory, or not kept): Watch cannot read them.
  bool levels_dropped() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return !dropped_reason_.empty();
  }
  // Memory taken by the kept levels (counted in the registry's budget).
  uint64_t kept_bytes() const { return kept_bytes_.load(std::memory_order_relaxed); }
  // Frees the kept levels (the registry drops the record): watchers end with NOT_FOUND
  // and `reason`. Returns the bytes freed. Called with the registry's lock held.
  uint64_t DropLevels(const std::string& reason);

  // The watcher's side. Fills `event` with what comes next for `cursor` and returns
  // kEvent; kEnd once everything was sent (`status` is the call's status); or kWait after
  // registering `waiter`, woken once when something new arrives.
  enum class Next { kEvent, kWait, kEnd };
  Next NextEvent(WatchCursor& cursor, v1::JobEvent& event, grpc::Status& status,
                 const std::shared_ptr<RecordWaiter>& waiter);

 private:
  struct Level {  // 24 bytes: the 8-byte fields first
    double energy;
    uint64_t triplet_end;  // triplets [end of the previous level, triplet_end)
    uint32_t cluster_count;
    uint32_t source_level;
  };

  // Levels a watcher can read: the snapshot (level 0) and the complete levels after it.
  uint32_t ReadableLevelsLocked() const;
  // Reserves memory for `event`'s levels and stores them.
  enum class Stored { kStored, kClosed, kNoRoom, kInconsistent };
  Stored Store(const v1::JobEvent& event);
  bool StoreLocked(const v1::JobEvent& event);
  void WakeAll(std::unique_lock<std::mutex>& lock);
  void EndLocked(v1::JobEvent final_event, const grpc::Status& status);
  void BuildSnapshotLocked(WatchCursor& cursor) const;
  void FillLevelBatchLocked(WatchCursor& cursor, v1::LevelBatch& batch) const;
  static uint64_t BytesOf(const v1::JobEvent& event);

  JobRegistry* const registry_;
  const std::string id_;
  const std::string tenant_;
  std::string owner_;
  const v1::JobSpec spec_;
  const bool detached_;
  const size_t max_event_bytes_;
  const absl::Time accepted_at_;
  std::weak_ptr<Job> job_;
  v1::Accepted accepted_;
  std::atomic<bool> cancelled_{false};
  std::atomic<bool> ended_{false};
  std::atomic<uint64_t> kept_bytes_{0};

  mutable std::mutex mutex_;
  JobState state_ = JobState::kQueued;
  absl::Time started_at_ = absl::InfinitePast();
  absl::Time ended_at_ = absl::InfinitePast();
  grpc::Status status_;
  v1::JobEvent final_event_;
  bool final_set_ = false;
  std::string dropped_reason_;  // set once the levels were dropped
  v1::Progress progress_;
  uint64_t progress_seq_ = 0;
  // The kept hierarchy: the snapshot (level 0) and the levels after it.
  std::vector<uint32_t> snapshot_labels_;
  uint32_t total_elements_ = 0;
  bool snapshot_complete_ = false;
  uint32_t snapshot_cluster_count_ = 0;
  double snapshot_energy_ = 0;
  uint32_t snapshot_source_level_ = 0;
  std::vector<Level> levels_;
  bool last_level_open_ = false;  // the last level continues in the next batch
  std::vector<uint32_t> element_, to_cluster_, from_cluster_;
  uint64_t levels_total_ = 0, triplets_total_ = 0;  // counted for every job
  std::vector<std::weak_ptr<RecordWaiter>> waiters_;
  // The labels at a level > 0 built for watchers starting there, while any still sends
  // them (BuildSnapshotLocked).
  mutable std::map<uint32_t, std::weak_ptr<const std::vector<uint32_t>>> level_labels_;
};

struct JobRegistryOptions {
  // How long an ended job stays (state, and a detached job's levels).
  absl::Duration retention = absl::Hours(1);
  // Memory the kept levels of all jobs may take together.
  uint64_t kept_bytes_limit = uint64_t{1} << 30;
  // Records kept at most (the oldest ended ones go first).
  size_t max_records = 10000;
};

class JobRegistry {
 public:
  explicit JobRegistry(JobRegistryOptions options);

  void Add(std::shared_ptr<JobRecord> record);
  // Takes a record out again (a job refused after it was registered).
  void Remove(const std::string& id);

  // The job `id` of `tenant`: NOT_FOUND when it was never known or is another tenant's
  // (the same code and message, so a tenant cannot tell others' jobs from unknown ids), or
  // when it was dropped (the message says when and why; only to its own tenant).
  absl::StatusOr<std::shared_ptr<JobRecord>> Find(const std::string& id, const std::string& tenant);
  // The jobs of `tenant`, in submission order; with `owner`, only those whose owner() is
  // `*owner` (a caller without tokens sees its own connection's jobs).
  std::vector<v1::JobSummary> List(const std::string& tenant, const std::string* owner = nullptr);
  // Jobs of `tenant` queued or running.
  uint32_t ActiveJobs(const std::string& tenant);
  // Calls visit(record) for every record, under the registry's lock (keep it short).
  template <typename Visit>
  void ForEach(Visit visit) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& [id, record] : records_) visit(*record);
  }

  // Reserves memory for a record's levels, dropping the oldest ended jobs' levels to make
  // room (for an attached job's record only other attached jobs'). False when even that is
  // not enough.
  bool ReserveKept(uint64_t bytes, const JobRecord* for_record);
  void ReleaseKept(uint64_t bytes) { kept_.Release(bytes); }

  // Drops the records ended longer than the retention time ago.
  void Sweep();

  size_t size();
  uint64_t kept_bytes() const { return kept_.used(); }
  uint64_t kept_limit() const { return kept_.limit(); }
  uint64_t dropped() const { return dropped_.load(std::memory_order_relaxed); }
  absl::Duration retention() const { return options_.retention; }

 private:
  // `id` by value: callers pass an element of order_, which this erases.
  void DropLocked(std::string id, const std::string& reason);

  const JobRegistryOptions options_;
  MemoryBudget kept_;
  std::atomic<uint64_t> dropped_{0};
  std::mutex mutex_;
  std::deque<std::string> order_;  // ids in submission order
  std::map<std::string, std::shared_ptr<JobRecord>> records_;
  // Why a job is gone, for NOT_FOUND messages (the newest few thousand).
  std::deque<std::string> dropped_order_;
  std::map<std::string, std::pair<std::string, std::string>> dropped_reasons_;  // tenant, why
};

// The channel of an attached job: its call's channel, with a copy of every event kept in
// the job's record, so the job can be watched like a detached one. Cancellation is the
// call's (the call going away cancels the job); Abort reaches both. A call whose reader
// was cut off releases the job (ResultStore::KeepJobOnCutOff): it runs on for its record,
// unless the record cannot keep its levels either (then it is cancelled).
class RecordingChannel : public EventChannel {
 public:
  RecordingChannel(std::shared_ptr<EventChannel> call, std::shared_ptr<JobRecord> record)
      : call_(std::move(call)), record_(std::move(record)) {}

  bool Emit(v1::JobEvent event) override;
  void Finish(v1::JobEvent final_event, const grpc::Status& status) override;
  void Abort(const grpc::Status& status) override;
  bool cancelled() const override { return call_->cancelled(); }
  const std::atomic<bool>* cancel_flag() const override { return call_->cancel_flag(); }

 private:
  const std::shared_ptr<EventChannel> call_;
  const std::shared_ptr<JobRecord> record_;
};

}  // namespace mlclust::server

#endif  // MLCLUST_SERVER_JOB_RECORD_H_
