// A job as it travels from the RPC handler through the queue to a worker.
#ifndef MLCLUST_SERVER_JOB_H_
#define MLCLUST_SERVER_JOB_H_

#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "absl/time/time.h"
#include "core/cluster/registry.h"
#include "grpcpp/support/status.h"
#include "mlclust/v1/mlclust.pb.h"

namespace mlclust::server {

// The outgoing half of a job's call. The worker emits events; the call writes them to the
// client in order. Thread-safe.
class EventChannel {
 public:
  virtual ~EventChannel() = default;

  // Queues `event` for the client and returns at once: producing never waits on a reader
  // (a reader that falls too far behind is cut off instead; see ResultStore). Returns
  // false once the job is cancelled (by the client, its deadline, a reader cut off, or the
  // server draining): the job should stop.
  virtual bool Emit(v1::JobEvent event) = 0;

  // Queues the final event (its `final` flag is set here) and ends the call with `status`
  // once every queued event is written. Only the first call has an effect.
  virtual void Finish(v1::JobEvent final_event, const grpc::Status& status) = 0;

  virtual bool cancelled() const = 0;

  // Cancels the job and ends it now with `status`, after a final Failed event carrying it
  // where one can still be sent: drain, Cancel. The default ends it through Finish.
  virtual void Abort(const grpc::Status& status) {
    v1::JobEvent failed;
    failed.mutable_failed()->set_code(status.error_code());
    failed.mutable_failed()->set_message(status.error_message());
    Finish(std::move(failed), status);
  }

  // The flag cancelled() reads, for drivers' options (core/base/cancel.h). Valid as long
  // as the channel. The server's channel (ResultStore) has one; null (never cancelled)
  // for channels without.
  virtual const std::atomic<bool>* cancel_flag() const { return nullptr; }

  // The call's reader was cut off but the job was released to run on for its record
  // (ResultStore::KeepJobOnCutOff): Emit returns false, yet the job need not stop.
  virtual bool released() const { return false; }
};

// Which worker runs a job.
enum class JobLane {
  kGl,   // the worker that owns the GL context (jobs planned for the GPU)
  kCpu,  // the pool of CPU workers (--workers N); with none, the GL worker takes these too
};

class JobRecord;

struct Job {
  std::string id;
  v1::JobSpec spec;
  std::string input;  // the whole upload: Draco bytes or float32 points
  std::shared_ptr<EventChannel> events;
  absl::Time accepted_at;
  std::string peer;  // the client's address, for logs
  JobLane lane = JobLane::kGl;
  // The plan made at submit, its devices included (server/job_runner.h PlanJobOnDevice);
  // the lane is its. Empty where planning failed (the runner plans again and reports the
  // error) or where the job did not come through the service (tests call RunJob).
  std::optional<JobPlan> plan;
  // Bytes of `input` counted against the server's queued-input budget until the job
  // leaves the queue.
  uint64_t queued_bytes = 0;
  // The job's entry in the server's registry (state, tenant; for a detached job also its
  // kept levels, and then the same object as `events`).
  std::shared_ptr<JobRecord> record;
  std::string tenant;

  // Set when the job is cancelled: client cancel, deadline, a reader cut off, drain.
  // Drivers take it in their options (`cancel = job.cancel_flag()`) and stop at the next
  // check with CANCELLED.
  const std::atomic<bool>* cancel_flag() const { return events->cancel_flag(); }
};

}  // namespace mlclust::server

#endif  // MLCLUST_SERVER_JOB_H_
