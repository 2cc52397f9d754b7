// A job as it travels from the RPC handler through the queue to the worker.
#ifndef MLCLUST_SERVER_JOB_H_
#define MLCLUST_SERVER_JOB_H_

#include <memory>
#include <string>

#include "absl/time/time.h"
#include "grpcpp/support/status.h"
#include "mlclust/v1/mlclust.pb.h"

namespace mlclust::server {

// The outgoing half of a job's call. The worker emits events; the RPC handler writes them
// to the client in order. Thread-safe.
class EventChannel {
 public:
  virtual ~EventChannel() = default;

  // Queues `event` for the client. Returns false once the call is cancelled (by the
  // client, its deadline or shutdown): the job should stop. While the client reads slower
  // than the job produces, blocks until the backlog is small again, so a slow reader
  // bounds the server's memory instead of growing it.
  virtual bool Emit(v1::JobEvent event) = 0;

  // Queues the final event (its `final` flag is set here) and ends the call with `status`
  // once every queued event is written. Call exactly once.
  virtual void Finish(v1::JobEvent final_event, const grpc::Status& status) = 0;

  virtual bool cancelled() const = 0;
};

struct Job {
  std::string id;
  v1::JobSpec spec;
  std::string input;  // the whole upload: Draco bytes or float32 points
  std::shared_ptr<EventChannel> events;
  absl::Time accepted_at;
};

}  // namespace mlclust::server

#endif  // MLCLUST_SERVER_JOB_H_
