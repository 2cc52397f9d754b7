// The mlclust gRPC server: the Clustering service, a bounded job queue and the worker
// thread that owns the GL context.
//
// One Server owns one worker thread. The worker creates the GL context (when allowed and
// available) on its own thread, once, and runs queued jobs there in order. Calls are
// handled with gRPC's callback API; no gRPC thread ever runs a job.
#ifndef MLCLUST_SERVER_SERVER_H_
#define MLCLUST_SERVER_SERVER_H_

#include <cstdint>
#include <memory>
#include <string>

#include "absl/status/statusor.h"
#include "grpcpp/channel.h"

namespace mlclust::server {

enum class GpuMode {
  kAuto,  // use a GL context when one can be created, else the CPU
  kOn,    // refuse to start without a GL context
  kOff,   // never create one
};

struct ServerOptions {
  // Address to listen on, e.g. "0.0.0.0:50051" or "127.0.0.1:0" (any free port). Empty:
  // no network listener, only InProcessChannel() (the CLI's embedded server).
  std::string listen_address;
  // Jobs that may wait in the queue (the running job not counted); more are refused with
  // RESOURCE_EXHAUSTED at once.
  size_t queue_capacity = 16;
  // Largest input a job may upload; larger ones are refused with RESOURCE_EXHAUSTED
  // before any byte is read.
  uint64_t max_input_bytes = uint64_t{1} << 30;
  // Events a job has produced and its client not yet read (memory, not wire bytes): per
  // job and over all jobs. A reader that falls further behind is cut off with
  // RESOURCE_EXHAUSTED and its job cancelled; producing levels never waits on a reader.
  uint64_t result_job_budget_bytes = uint64_t{256} << 20;
  uint64_t result_server_budget_bytes = uint64_t{1} << 30;
  // Largest message sent; larger level batches and snapshots are split (under gRPC's
  // default 4 MiB receive limit).
  size_t max_event_bytes = size_t{3} << 20;
  GpuMode gpu = GpuMode::kAuto;
  // Log lines (start-up, renderer, each job) to stderr.
  bool log = true;
};

class ServerImpl;

class Server {
 public:
  // Starts the worker (creating the GL context on it) and the gRPC server. Returns
  // UNAVAILABLE if the address cannot be bound or GpuMode::kOn finds no GL device.
  static absl::StatusOr<std::unique_ptr<Server>> Start(const ServerOptions& options);
  ~Server();  // Shutdown()

  // The port bound for listen_address (the chosen one for port 0), or 0 if none.
  int port() const;
  // A channel to this server inside the process, no network involved.
  std::shared_ptr<grpc::Channel> InProcessChannel();
  // The GL renderer the worker got ("" without a GL context) and why there is none.
  std::string gl_renderer() const;
  std::string gl_unavailable_reason() const;

  // Blocks until Shutdown() is called from another thread or a signal handler.
  void Wait();
  // Stops accepting calls, cancels running and queued jobs, joins the worker. Idempotent.
  void Shutdown();

 private:
  explicit Server(std::unique_ptr<ServerImpl> impl);
  std::unique_ptr<ServerImpl> impl_;
};

}  // namespace mlclust::server

#endif  // MLCLUST_SERVER_SERVER_H_
