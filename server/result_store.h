// A job's bounded store of events, between the worker that produces them and the call
// that streams them to the client.
//
// Producing never waits on a reader: Emit appends to the store and returns at once. The
// store holds the events not yet written to the client within two budgets, counted in
// memory (SpaceUsedLong, not serialized bytes): the job's own and the server-wide one
// shared by every job. An event that would exceed either cuts the reader off: the held
// events are dropped, the call ends with RESOURCE_EXHAUSTED saying why, and the job is
// cancelled (cancel_flag() set, Emit returns false), so the worker moves on; or, for a job
// whose record keeps its levels (KeepJobOnCutOff), the job is released: it runs on, the
// call's end says to Watch it, and nothing the call does later cancels it.
//
// No message is larger than `max_event_bytes` serialized: bigger level batches are split
// across LevelBatch messages (LevelBatch.last_level_continues) and bigger snapshots by
// element range, so default-limit clients (4 MiB) can read any job.
#ifndef MLCLUST_SERVER_RESULT_STORE_H_
#define MLCLUST_SERVER_RESULT_STORE_H_

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <vector>

#include "server/job.h"
#include "server/memory_budget.h"

namespace mlclust::server {

// The call side of a store: starts one write at a time and ends the call. Implemented by
// the call's reactor; the store calls it without holding its own lock.
class EventWriter {
 public:
  virtual ~EventWriter() = default;
  virtual void StartWrite(const v1::JobEvent* event) = 0;
  virtual void Finish(const grpc::Status& status) = 0;
};

struct ResultStoreOptions {
  // Unread events one job may hold (memory) before its reader is cut off.
  uint64_t job_budget_bytes = uint64_t{256} << 20;
  // Largest serialized event sent; bigger ones are split. Under gRPC's default 4 MiB
  // receive limit with room for the frame.
  size_t max_event_bytes = size_t{3} << 20;
  // Called once when the reader is cut off (for counters and logs).
  std::function<void(const grpc::Status&)> on_cut_off;
  // Where the serialized bytes written to the client are counted (metrics), if set.
  std::atomic<uint64_t>* bytes_written = nullptr;
};

// `max_bytes` >= 1 KiB. Splits a LevelBatch or LevelSnapshot event whose serialized size
// is over `max_bytes` into consecutive events each at most `max_bytes`; any other event,
// or one that fits, comes back alone. The pieces rebuild exactly the same levels.
std::vector<v1::JobEvent> SplitLargeEvent(v1::JobEvent event, size_t max_bytes);

class ResultStore : public EventChannel {
 public:
  // `server_budget` (shared, outlives the store) bounds all stores together.
  ResultStore(EventWriter* writer, MemoryBudget* server_budget, ResultStoreOptions options);
  ~ResultStore() override;

  // EventChannel (the job's side).
  bool Emit(v1::JobEvent event) override;
  void Finish(v1::JobEvent final_event, const grpc::Status& status) override;
  bool cancelled() const override { return cancelled_.load(std::memory_order_relaxed); }
  const std::atomic<bool>* cancel_flag() const override { return &cancelled_; }

  // Cancels the job and ends the call now with `status` (after a final Failed event
  // carrying it, if the call can still take one): drain, an operator's cancel.
  void Abort(const grpc::Status& status) override;

  // The job `job_id` keeps its levels elsewhere (its record, for Watch): a reader cut off
  // releases the job instead of cancelling it, and is told to watch it. Call before the
  // job is queued.
  void KeepJobOnCutOff(std::string job_id);
  // The reader was cut off and the job released: it no longer depends on this call.
  bool released() const override { return released_.load(std::memory_order_acquire); }
  // Shutdown: events still unread are dropped and the call ends with a final Failed
  // `status` as soon as the write in flight is done, so a slow reader still gets a final
  // event in the time left. Nothing changes for a call with nothing unread.
  void FlushForShutdown(const grpc::Status& status);

  // The writer's side.
  void OnWriteDone(bool ok);
  void OnCancel();  // the client cancelled, its deadline passed, or the server shut down
  void Detach();    // the call is done; nothing more is written

  // Memory held by unread events.
  uint64_t held_bytes() const;

 private:
  void Push(v1::JobEvent event, std::unique_lock<std::mutex>& lock);
  // `why` (the reader read too slowly): cancels the job, or releases it (KeepJobOnCutOff).
  void CutOff(const std::string& why, std::unique_lock<std::mutex>& lock);
  void CancelJobLocked();  // cancels the job unless it was released
  void DropHeld();
  // Holds a final Failed event with `status` and asks for the end with it (mutex held).
  void HoldFailed(const grpc::Status& status);
  // Starts the next write, or ends the call when nothing is left and an end was asked
  // for. Called with `lock` held; releases it before calling the writer, so a reaction
  // that runs inline cannot deadlock on mutex_.
  void Pump(std::unique_lock<std::mutex>& lock);

  const ResultStoreOptions options_;
  MemoryBudget* const server_budget_;
  mutable std::mutex mutex_;
  EventWriter* writer_;  // null after Detach
  struct Held {
    v1::JobEvent event;
    uint64_t bytes;
  };
  std::deque<Held> held_;
  uint64_t held_bytes_ = 0;
  v1::JobEvent in_flight_;  // must outlive its write
  bool write_in_flight_ = false;
  bool finish_requested_ = false;
  bool finished_ = false;     // the writer's Finish was called
  bool client_gone_ = false;  // cancelled by the client, its deadline or shutdown
  grpc::Status finish_status_;
  std::atomic<bool> cancelled_{false};
  std::atomic<bool> released_{false};
  std::string keep_job_id_;  // KeepJobOnCutOff
};

}  // namespace mlclust::server

#endif  // MLCLUST_SERVER_RESULT_STORE_H_
