// The mlclust gRPC server: the Clustering service, a bounded job queue and the worker
// thread that owns the GL context.
//
// One Server owns one worker thread that creates the GL context (when allowed and
// available) on its own thread, once, and runs jobs there in order, and optionally a pool
// of CPU workers (ServerOptions::cpu_workers). Calls are handled with gRPC's callback API;
// no gRPC thread ever runs a job, and producing a job's levels never waits on its client
// (server/result_store.h).
#ifndef MLCLUST_SERVER_SERVER_H_
#define MLCLUST_SERVER_SERVER_H_

#include <cstdint>
#include <map>
#include <memory>
#include <string>

#include "absl/status/statusor.h"
#include "absl/time/time.h"
#include "grpcpp/channel.h"

namespace mlclust::server {

enum class GpuMode {
  kAuto,  // use a GL context when one can be created, else the CPU
  kOn,    // refuse to start without a GL context
  kOff,   // never create one
};

struct ServerOptions {
  // Address to listen on, e.g. "127.0.0.1:50051" or "127.0.0.1:0" (any free port). Empty:
  // no network listener, only InProcessChannel() (the CLI's embedded server). A port in
  // use is refused (no SO_REUSEPORT). A non-loopback address logs a warning (no TLS).
  std::string listen_address;
  // Jobs that may wait in the queue (the running job not counted); more are refused with
  // RESOURCE_EXHAUSTED at once.
  size_t queue_capacity = 16;
  // Largest input a job may upload; larger ones are refused with RESOURCE_EXHAUSTED
  // before any byte is read.
  uint64_t max_input_bytes = uint64_t{1} << 30;
  // Admission, before anything is allocated for a call; each refusal is answered with
  // RESOURCE_EXHAUSTED and a message, logged and counted (Stats.calls_refused).
  // Run calls in progress (uploading, queued, running or streaming): in total, per
  // connection and per client address.
  uint32_t max_calls = 256;
  uint32_t max_calls_per_connection = 32;
  uint32_t max_calls_per_peer = 64;
  // With tokens: calls in progress per tenant (0: no limit), so one tenant's stalled calls
  // cannot take the slots of the others behind the same address or proxy.
  uint32_t max_calls_per_tenant = 64;
  // Uploads must make progress: a Run call that receives nothing (no spec, no input
  // bytes) for `upload_idle_timeout`, or whose input arrives slower than
  // `upload_min_bytes_per_second` on average (it may take upload_idle_timeout +
  // received / rate), is ended with DEADLINE_EXCEEDED saying which, so stalled calls give
  // back their admission slots and upload memory. The timeout must be over 0 and at most
  // 1 hour; a rate of 0 turns the rate check off (at most 1 GiB/s).
  absl::Duration upload_idle_timeout = absl::Seconds(30);
  uint64_t upload_min_bytes_per_second = uint64_t{64} << 10;
  // A Watch call whose client takes no event for this long is cut off (its admission
  // slot given back at once; RESOURCE_EXHAUSTED when it reads again; cancelled after one
  // more such time). Watch calls are admitted like Run calls (max_calls and the limits
  // per connection, address and tenant) and the event each is writing counts in
  // `result_server_budget_bytes`. Over 0, at most 1 hour.
  absl::Duration watch_idle_timeout = absl::Seconds(60);
  // Bytes received into uploads not yet complete, over all calls. Buffers grow as data
  // arrives; nothing is reserved from a declared size.
  uint64_t max_upload_bytes_in_flight = uint64_t{1} << 30;
  // The inputs of the jobs waiting in the queue, together.
  uint64_t max_queued_input_bytes = uint64_t{4} << 30;
  // CPU workers beside the worker that owns the GL context. With none, the GL worker runs
  // every job in order; with some, it runs the jobs planned for the GPU (meshes with
  // device "gpu", or "auto" on a hardware GL) and the CPU workers the rest.
  size_t cpu_workers = 0;
  // On Shutdown, running jobs may finish within this time; then they are cancelled.
  // Queued jobs end at once with UNAVAILABLE.
  absl::Duration drain_time = absl::ZeroDuration();
  // Events a job has produced and its client not yet read (memory, not wire bytes): per
  // job and over all jobs. A reader that falls further behind is cut off with
  // RESOURCE_EXHAUSTED; its job runs on where its record keeps its levels (the message says
  // to watch it) and is cancelled only where they cannot be kept. Producing levels never
  // waits on a reader. At Shutdown, a call's unread events are dropped so it still gets a
  // final event.
  uint64_t result_job_budget_bytes = uint64_t{256} << 20;
  uint64_t result_server_budget_bytes = uint64_t{1} << 30;
  // Largest message sent; larger level batches and snapshots are split (under gRPC's
  // default 4 MiB receive limit).
  size_t max_event_bytes = size_t{3} << 20;
  // Detached jobs (JobSpec.detach) keep their levels for Watch: an ended job stays this
  // long, and the kept levels of all jobs take at most `kept_results_bytes` (the oldest
  // ended jobs' are dropped first to make room; a job that cannot fit is cancelled).
  absl::Duration result_retention = absl::Hours(1);
  uint64_t kept_results_bytes = uint64_t{1} << 30;
  // Jobs one tenant may have queued or running at once (0: no limit); more are refused
  // with RESOURCE_EXHAUSTED.
  uint32_t max_jobs_per_tenant = 0;
  // TLS: the server's certificate chain and private key (PEM text). Empty: plaintext.
  std::string tls_cert_pem, tls_key_pem;
  // With TLS: clients must present a certificate signed by this CA (PEM text).
  std::string tls_client_ca_pem;
  // Bearer tokens, token -> tenant (server/auth.h); they need TLS. With them every
  // Clustering call needs a known token (UNAUTHENTICATED otherwise) and sees only its
  // tenant's jobs (another's answers NOT_FOUND exactly like an unknown id). Empty: one
  // tenant, "".
  std::map<std::string, std::string> auth_tokens;
  // Without tokens, ListJobs shows a caller only the jobs its own connection submitted
  // (job ids are unguessable capabilities: Watch and Cancel work for whoever holds one).
  // True: every job (a single-user server). Ignored with tokens (a tenant sees its own).
  bool list_all_jobs = false;
  GpuMode gpu = GpuMode::kAuto;
  // Log lines (start-up, renderer, each job) to stderr.
  bool log = true;
  // One JSON object per log line (job id, tenant, algorithm, sizes, durations, outcome)
  // instead of text. Process-wide: the last server started decides.
  bool log_json = false;
  // "HOST:PORT" for Prometheus metrics over HTTP (GET /metrics; port 0 picks one); empty:
  // none. A port in use is refused.
  std::string metrics_address;
  // Where tokens are on, a metrics address that is not loopback is refused at start (the
  // exposition is plain HTTP without a token) unless this is set (a network that is
  // already private). Metrics answer under idle or slow connections: 32 workers, and a
  // connection idle for 1 s is dropped.
  bool metrics_allow_remote = false;
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
  // The metrics port (the chosen one for port 0), or 0 without metrics.
  int metrics_port() const;
  // A channel to this server inside the process, no network involved.
  std::shared_ptr<grpc::Channel> InProcessChannel();
  // The GL renderer the worker got ("" without a GL context) and why there is none.
  std::string gl_renderer() const;
  std::string gl_unavailable_reason() const;

  // Blocks until Shutdown() is called from another thread or a signal handler.
  void Wait();
  // Drains: health NOT_SERVING and new calls refused (UNAVAILABLE) at once; queued jobs
  // end with a final Failed UNAVAILABLE; running jobs get `drain_time` to finish, then are
  // cancelled; calls still open 2 s later are cancelled; the workers are joined.
  // Idempotent.
  void Shutdown();

 private:
  explicit Server(std::unique_ptr<ServerImpl> impl);
  std::unique_ptr<ServerImpl> impl_;
};

}  // namespace mlclust::server

#endif  // MLCLUST_SERVER_SERVER_H_
