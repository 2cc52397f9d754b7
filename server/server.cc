#include "server/server.h"

#include <malloc.h>
#include <sys/random.h>
#include <zlib.h>

#include <atomic>
#include <cerrno>
#include <condition_variable>
#include <future>
#include <map>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/time/clock.h"
#include "core/cluster/registry.h"
#include "grpc/grpc.h"
#include "grpcpp/ext/proto_server_reflection_plugin.h"
#include "grpcpp/grpcpp.h"
#include "grpcpp/health_check_service_interface.h"
#include "mlclust/v1/mlclust.grpc.pb.h"
#include "server/auth.h"
#include "server/job.h"
#include "server/job_options.h"
#include "server/job_queue.h"
#include "server/job_record.h"
#include "server/job_runner.h"
#include "server/log.h"
#include "server/memory_budget.h"
#include "server/metrics.h"
#include "server/result_store.h"
#ifdef MLCLUST_HAVE_GPU
#include "gpu/context/gl_context.h"
#include "gpu/stages/gl_device_stages.h"
#include "gpu/stages/gpu_working_set.h"
#endif

namespace mlclust::server {
namespace {

constexpr char kServiceName[] = "mlclust.v1.Clustering";
// Largest message a client may send; chunks are ~1 MiB, so this leaves room.
constexpr int kMaxReceiveMessageBytes = 64 << 20;

grpc::Status ToGrpc(const absl::Status& status) {
  return grpc::Status(static_cast<grpc::StatusCode>(status.code()), std::string(status.message()));
}

v1::JobEvent FailedEvent(const grpc::Status& status) {
  v1::JobEvent event;
  event.mutable_failed()->set_code(status.error_code());
  event.mutable_failed()->set_message(status.error_message());
  return event;
}

// "ipv4:10.0.0.1:5000" -> "ipv4:10.0.0.1"; "ipv6:[::1]:5000" -> "ipv6:[::1]": the client's
// address without its port (one client host may open several connections).
std::string PeerHost(const std::string& peer) {
  const size_t colon = peer.rfind(':');
  const size_t scheme = peer.find(':');
  if (colon == std::string::npos || colon == scheme) return peer;
  return peer.substr(0, colon);
}

// A connection's peer string names that one connection (address and port), so ListJobs
// can show a caller its own connection's jobs; unix-socket and in-process peers do not.
bool NamesOneConnection(const std::string& peer) {
  return absl::StartsWith(peer, "ipv4:") || absl::StartsWith(peer, "ipv6:");
}

// "job-" and 128 bits from the kernel's CSPRNG as 32 lowercase hex digits: a job id is a
// capability (Watch, Cancel), so it must not be guessable from other ids.
absl::StatusOr<std::string> RandomJobId() {
  unsigned char bytes[16];
  size_t have = 0;
  while (have < sizeof(bytes)) {
    const ssize_t got = getrandom(bytes + have, sizeof(bytes) - have, 0);
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) {
      return absl::InternalError(
          absl::StrCat("no random job id: getrandom failed (errno ", errno, ")"));
    }
    have += static_cast<size_t>(got);
  }
  std::string id = "job-";
  for (unsigned char byte : bytes) absl::StrAppend(&id, absl::Hex(byte, absl::kZeroPad2));
  return id;
}

// A status code's name for logs ("RESOURCE_EXHAUSTED"), not its number.
std::string CodeName(int code) {
  return absl::StatusCodeToString(static_cast<absl::StatusCode>(code));
}

bool IsLoopback(const std::string& address) {
  return absl::StartsWith(address, "127.") || absl::StartsWith(address, "localhost:") ||
         absl::StartsWith(address, "[::1]:") || absl::StartsWith(address, "unix:");
}

// The registry's name of a job's algorithm ("ml", "lnkmeans", ...), for logs and metrics.
std::string AlgorithmName(const v1::JobSpec& spec) {
  const InputKind input =
      spec.input_kind() == v1::INPUT_KIND_POINTS_F32 ? InputKind::kPoints : InputKind::kMesh;
  const AlgorithmInfo* algorithm = FindAlgorithmByWire(
      input, spec.algorithm() == v1::ALGORITHM_UNSPECIFIED ? v1::ALGORITHM_ML : spec.algorithm());
  // One label for every unknown value (a client's number is not a label).
  return algorithm != nullptr ? algorithm->name : std::string("unknown");
}

const char* InputKindText(const v1::JobSpec& spec) {
  switch (spec.input_kind()) {
    case v1::INPUT_KIND_DRACO_MESH:
      return "mesh";
    case v1::INPUT_KIND_POINTS_F32:
      return "points";
    default:
      return "unknown";
  }
}

struct Counters {
  std::atomic<uint64_t> accepted{0}, succeeded{0}, failed{0}, cancelled{0}, rejected{0},
      readers_cut_off{0}, calls_refused{0}, uploads_timed_out{0};
  // Input bytes received and serialized event bytes written (Run and Watch calls).
  std::atomic<uint64_t> bytes_in{0}, bytes_out{0};
  std::atomic<uint32_t> jobs_running{0};
};

// Calls in progress, in total, per connection, per client address and (with tokens) per
// tenant. Admission comes before any allocation for the call.
class CallAdmission {
 public:
  explicit CallAdmission(const ServerOptions& options) : options_(options) {}

  // OK and counted, or RESOURCE_EXHAUSTED saying which limit. `tenant` counts only on a
  // server with tokens (without, every caller is the one tenant "").
  absl::Status Admit(const std::string& peer, const std::string& tenant) {
    std::lock_guard<std::mutex> lock(mutex_);
    const std::string host = PeerHost(peer);
    const bool per_tenant = !options_.auth_tokens.empty() && options_.max_calls_per_tenant > 0;
    if (total_ >= options_.max_calls) {
      return absl::ResourceExhaustedError(absl::StrCat(
          "the server has ", total_, " calls in progress, its limit; try again later"));
    }
    if (Count(by_connection_, peer) >= options_.max_calls_per_connection) {
      return absl::ResourceExhaustedError(
          absl::StrCat("this connection has ", options_.max_calls_per_connection,
                       " calls in progress, the server's limit per connection; try again later"));
    }
    if (Count(by_host_, host) >= options_.max_calls_per_peer) {
      return absl::ResourceExhaustedError(
          absl::StrCat("this client address has ", options_.max_calls_per_peer,
                       " calls in progress, the server's limit per address; try again later"));
    }
    if (per_tenant && Count(by_tenant_, tenant) >= options_.max_calls_per_tenant) {
      return absl::ResourceExhaustedError(
          absl::StrCat("tenant '", tenant, "' has ", options_.max_calls_per_tenant,
                       " calls in progress, the server's limit per tenant; try again later"));
    }
    ++total_;
    ++by_connection_[peer];
    ++by_host_[host];
    if (per_tenant) ++by_tenant_[tenant];
    return absl::OkStatus();
  }

  void Release(const std::string& peer, const std::string& tenant) {
    std::lock_guard<std::mutex> lock(mutex_);
    --total_;
    if (--by_connection_[peer] == 0) by_connection_.erase(peer);
    const std::string host = PeerHost(peer);
    if (--by_host_[host] == 0) by_host_.erase(host);
    if (auto it = by_tenant_.find(tenant); it != by_tenant_.end() && --it->second == 0) {
      by_tenant_.erase(it);
    }
  }

  uint32_t total() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return total_;
  }

 private:
  static uint32_t Count(const std::map<std::string, uint32_t>& counts, const std::string& key) {
    auto it = counts.find(key);
    return it == counts.end() ? 0 : it->second;
  }

  const ServerOptions& options_;
  mutable std::mutex mutex_;
  uint32_t total_ = 0;
  std::map<std::string, uint32_t> by_connection_, by_host_, by_tenant_;
};

class ServiceImpl;

// A call the watchdog can end: RunCall (its upload), WatchCall (a write its client does
// not take).
class WatchedUpload {
 public:
  virtual ~WatchedUpload() = default;
  // Marks the call ended (no read is started after this) and returns what ends the
  // call with `status`, which the watchdog runs once its lock is released (the call may
  // be gone by then: the closure holds what it needs). Called on the watchdog's thread
  // with its lock held, so the call is alive (it leaves the watchdog before it is
  // deleted). `*rearm` set: watch the call again (one more idle timeout).
  virtual std::function<void()> EndUpload(const grpc::Status& status, bool* rearm) = 0;
};

// Uploads must make progress: the Run calls still receiving their spec or input, each
// ended (DEADLINE_EXCEEDED, saying why) when nothing arrived for the idle timeout, or when
// it has received less than the minimum rate allows: a call may take
// idle_timeout + received / min_rate. One thread checks every call a few times per idle
// timeout.
class UploadWatchdog {
 public:
  UploadWatchdog(absl::Duration idle_timeout, uint64_t min_bytes_per_second,
                 absl::Duration write_idle_timeout)
      : idle_timeout_(idle_timeout),
        min_rate_(min_bytes_per_second),
        write_idle_timeout_(write_idle_timeout) {}
  ~UploadWatchdog() { Stop(); }

  void Start() {
    thread_ = std::thread([this] { Main(); });
  }
  void Stop() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    if (thread_.joinable()) thread_.join();
  }

  void Add(WatchedUpload* call, uint64_t declared_bytes = 0) {
    std::lock_guard<std::mutex> lock(mutex_);
    const absl::Time now = absl::Now();
    calls_[call] = {now, now, 0, declared_bytes, false};
  }
  // A write the client must take within the write idle timeout (WatchCall).
  void AddWrite(WatchedUpload* call) {
    std::lock_guard<std::mutex> lock(mutex_);
    const absl::Time now = absl::Now();
    calls_[call] = {now, now, 0, 0, true};
  }
  void Progress(WatchedUpload* call, uint64_t bytes, uint64_t declared_bytes) {
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = calls_.find(call);
    if (it == calls_.end()) return;
    it->second.last_progress = absl::Now();
    it->second.received += bytes;
    it->second.declared = declared_bytes;
  }
  // Takes `call` out: false when the watchdog has ended it already (then EndUpload was
  // called or is on its way).
  bool Remove(WatchedUpload* call) {
    std::lock_guard<std::mutex> lock(mutex_);
    return calls_.erase(call) > 0;
  }

 private:
  struct Upload {
    absl::Time started, last_progress;
    uint64_t received, declared;
    bool write;  // a write to the client, not an upload
  };

  void Main() {
    const absl::Duration tick = std::clamp(std::min(idle_timeout_, write_idle_timeout_) / 4,
                                           absl::Milliseconds(10), absl::Seconds(1));
    std::unique_lock<std::mutex> lock(mutex_);
    while (!stop_) {
      wake_.wait_for(lock, absl::ToChronoNanoseconds(tick));
      const absl::Time now = absl::Now();
      for (auto it = calls_.begin(); it != calls_.end();) {
        const Upload& upload = it->second;
        std::string why;
        const std::string sizes =
            upload.declared > 0 ? absl::StrCat(upload.received, " of ", upload.declared, " bytes")
                                : absl::StrCat(upload.received, " bytes, no job spec yet");
        if (upload.write) {
          if (now - upload.last_progress > write_idle_timeout_) {
            why = absl::StrCat(
                "the client read nothing for ", absl::FormatDuration(now - upload.last_progress),
                " (the server's limit is ", absl::FormatDuration(write_idle_timeout_), ")");
          }
        } else if (now - upload.last_progress > idle_timeout_) {
          why = absl::StrCat("the upload made no progress for ",
                             absl::FormatDuration(now - upload.last_progress), " (", sizes,
                             " received); the server ends uploads idle longer than ",
                             absl::FormatDuration(idle_timeout_));
        } else if (min_rate_ > 0 &&
                   now - upload.started >
                       idle_timeout_ + absl::Seconds(static_cast<double>(upload.received) /
                                                     static_cast<double>(min_rate_))) {
          why = absl::StrCat(
              "the upload is too slow: ", sizes, " received in ",
              absl::FormatDuration(now - upload.started), ", under the server's minimum rate of ",
              min_rate_, " bytes/s (after the first ", absl::FormatDuration(idle_timeout_), ")");
        }
        if (why.empty()) {
          ++it;
          continue;
        }
        WatchedUpload* call = it->first;
        const bool write = upload.write;
        calls_.erase(it);
        bool rearm = false;
        const std::function<void()> end =
            call->EndUpload(grpc::Status(write ? grpc::StatusCode::RESOURCE_EXHAUSTED
                                               : grpc::StatusCode::DEADLINE_EXCEEDED,
                                         why),
                            &rearm);
        if (rearm) calls_[call] = {now, now, 0, 0, write};
        lock.unlock();
        end();
        lock.lock();
        it = calls_.begin();  // the map may have changed meanwhile
      }
    }
  }

  const absl::Duration idle_timeout_;
  const uint64_t min_rate_;
  const absl::Duration write_idle_timeout_;
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stop_ = false;
  std::map<WatchedUpload*, Upload> calls_;
  std::thread thread_;
};

// The reactor of one Run call: reads the spec and the input chunks, submits the job,
// then writes the job's events through its ResultStore.
class RunCall : public grpc::ServerBidiReactor<v1::RunRequest, v1::JobEvent>, public WatchedUpload {
 public:
  // `refusal` not OK: the call was not admitted and is answered with it at once.
  RunCall(ServiceImpl* service, std::string peer, std::string tenant, const absl::Status& refusal);

  void OnReadDone(bool ok) override;
  void OnWriteDone(bool ok) override { channel_->OnWriteDone(ok); }
  void OnCancel() override;
  void OnDone() override;
  std::function<void()> EndUpload(const grpc::Status& status, bool* rearm) override;

 private:
  // The store's view of this reactor.
  class Writer : public EventWriter {
   public:
    explicit Writer(RunCall* call) : call_(call) {}
    void StartWrite(const v1::JobEvent* event) override { call_->StartWrite(event); }
    void Finish(const grpc::Status& status) override { call_->Finish(status); }

   private:
    RunCall* call_;
  };

  void Fail(const absl::Status& status);
  void Refuse(const absl::Status& status);         // Fail, logged and counted as a refusal
  void FailMalformed(const absl::Status& status);  // Fail, logged (call_failed)
  void Submit();
  void ReleaseUpload();
  // The next read, unless the watchdog has ended the upload (then false: nothing more is
  // read, the call's end is on its way).
  bool ReadNext();
  // Leaves the watchdog: false when it has ended the upload already.
  bool LeaveWatchdog();

  ServiceImpl* service_;
  const std::string peer_;
  const std::string tenant_;
  const bool admitted_;
  Writer writer_{this};
  std::shared_ptr<ResultStore> channel_;
  v1::RunRequest request_;
  v1::JobSpec spec_;
  bool have_spec_ = false;
  std::string input_;
  uint64_t upload_reserved_ = 0;  // bytes of input_ counted in the upload budget
  uint32_t input_crc32_ = 0;      // zlib's crc32 of input_, kept as chunks arrive
  // Uploads this big that never became a job are trimmed back to the system at the end.
  static constexpr size_t kTrimAfterBytes = size_t{16} << 20;
  bool held_big_upload_ = false;
  std::weak_ptr<Job> job_;
  // Set by the watchdog (EndUpload); no read is started after it.
  std::mutex read_mutex_;
  bool upload_ended_ = false;
  bool watched_ = false;  // in the watchdog's list
};

class ServiceImpl final : public v1::Clustering::CallbackService {
 public:
  explicit ServiceImpl(const ServerOptions& options)
      : options_(options),
        queue_(options.queue_capacity),
        admission_(options_),
        upload_budget_(options.max_upload_bytes_in_flight),
        queued_budget_(options.max_queued_input_bytes),
        result_budget_(options.result_server_budget_bytes),
        registry_(JobRegistryOptions{options.result_retention, options.kept_results_bytes}),
        uploads_(options.upload_idle_timeout, options.upload_min_bytes_per_second,
                 options.watch_idle_timeout) {}

  // A new job's store of events, writing to `writer`.
  std::shared_ptr<ResultStore> NewResultStore(EventWriter* writer) {
    ResultStoreOptions store_options;
    store_options.job_budget_bytes = options_.result_job_budget_bytes;
    store_options.max_event_bytes = options_.max_event_bytes;
    store_options.bytes_written = &counters_.bytes_out;
    store_options.on_cut_off = [this](const grpc::Status& status) {
      ++counters_.readers_cut_off;
      LogLine(options_.log, "a reader was cut off: ", status.error_message());
    };
    auto store = std::make_shared<ResultStore>(writer, &result_budget_, std::move(store_options));
    std::lock_guard<std::mutex> lock(stores_mutex_);
    std::erase_if(stores_, [](const std::weak_ptr<ResultStore>& weak) { return weak.expired(); });
    stores_.push_back(store);
    return store;
  }

  // Shutdown, once the jobs have ended: every call still holding events its client has
  // not read drops them and ends with a final Failed event, so a slow reader still gets
  // one before the calls are cancelled.
  void FlushCallsForShutdown() {
    std::vector<std::shared_ptr<ResultStore>> stores;
    {
      std::lock_guard<std::mutex> lock(stores_mutex_);
      for (const std::weak_ptr<ResultStore>& weak : stores_) {
        if (std::shared_ptr<ResultStore> store = weak.lock()) stores.push_back(std::move(store));
      }
    }
    const grpc::Status status(grpc::StatusCode::UNAVAILABLE,
                              "the server is shutting down and the client had not read all of "
                              "the job's events; submit the job again, to another server");
    for (const std::shared_ptr<ResultStore>& store : stores) store->FlushForShutdown(status);
  }

  grpc::ServerBidiReactor<v1::RunRequest, v1::JobEvent>* Run(
      grpc::CallbackServerContext* context) override {
    std::string peer = context->peer();
    absl::StatusOr<std::string> tenant = Authorize(context);
    absl::Status admitted = !tenant.ok() ? tenant.status()
                            : draining_  ? absl::UnavailableError(
                                               "the server is shutting down; submit the job to "
                                                "another server or try again later")
                                        : admission_.Admit(peer, *tenant);
    return new RunCall(this, std::move(peer), tenant.value_or(""), admitted);
  }

  grpc::ServerWriteReactor<v1::JobEvent>* Watch(grpc::CallbackServerContext* context,
                                                const v1::WatchRequest* request) override;

  // The call's tenant; UNAUTHENTICATED on a server with tokens when the call has none
  // (a wrong one never gets here: the token check refuses it).
  absl::StatusOr<std::string> Authorize(const grpc::ServerContextBase* context) const {
    if (options_.auth_tokens.empty()) return std::string();
    std::optional<std::string_view> authorization;
    const auto& metadata = context->client_metadata();
    if (auto header = metadata.find("authorization"); header != metadata.end()) {
      authorization = std::string_view(header->second.data(), header->second.size());
    }
    return TenantOfCall(options_.auth_tokens, authorization);
  }

  // A unary call refused by Authorize: finished with its status; nullptr when authorized.
  grpc::ServerUnaryReactor* RefuseUnauthorized(grpc::CallbackServerContext* context,
                                               std::string* tenant) {
    absl::StatusOr<std::string> authorized = Authorize(context);
    if (authorized.ok()) {
      *tenant = *authorized;
      return nullptr;
    }
    LogRefusal(context->peer(), "", "", authorized.status());
    grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
    reactor->Finish(ToGrpc(authorized.status()));
    return reactor;
  }

  grpc::ServerUnaryReactor* Cancel(grpc::CallbackServerContext* context,
                                   const v1::CancelRequest* request,
                                   v1::CancelReply* reply) override {
    std::string tenant;
    if (grpc::ServerUnaryReactor* refused = RefuseUnauthorized(context, &tenant)) return refused;
    grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
    absl::StatusOr<std::shared_ptr<JobRecord>> record = registry_.Find(request->job_id(), tenant);
    if (!record.ok()) {
      reactor->Finish(ToGrpc(record.status()));
      return reactor;
    }
    const grpc::Status cancelled(
        grpc::StatusCode::CANCELLED,
        absl::StrCat("job ", request->job_id(), " was cancelled by a Cancel call"));
    if (std::shared_ptr<Job> job = (*record)->job()) {
      if (queue_.Remove(job.get())) {
        LeftQueue(*job);
        ++counters_.cancelled;
        AnnounceQueuePositions();
      }
      job->events->Abort(cancelled);
      if ((*record)->state() == JobState::kQueued) {
        (*record)->MarkEnded(cancelled);
        JobEnded(*job, "cancelled", absl::Now(), absl::Now(), cancelled.error_code(),
                 cancelled.error_message(), nullptr);
      }
      LogLine(options_.log, LogSafe(request->job_id()), " cancelled by a Cancel call from ",
              LogSafe(context->peer()));
    }
    reply->set_state(JobStateName((*record)->state()));
    reactor->Finish(grpc::Status::OK);
    return reactor;
  }

  grpc::ServerUnaryReactor* ListJobs(grpc::CallbackServerContext* context,
                                     const v1::ListJobsRequest* request,
                                     v1::JobList* list) override {
    std::string tenant;
    if (grpc::ServerUnaryReactor* refused = RefuseUnauthorized(context, &tenant)) return refused;
    // Without tokens: the caller's own connection's jobs, unless every job is listed
    // (ServerOptions::list_all_jobs); a peer that names no one connection sees none.
    const std::string peer = context->peer();
    const bool own_connection = options_.auth_tokens.empty() && !options_.list_all_jobs;
    std::vector<v1::JobSummary> jobs;
    if (!own_connection || NamesOneConnection(peer)) {
      jobs = registry_.List(tenant, own_connection ? &peer : nullptr);
    }
    for (v1::JobSummary& summary : jobs) {
      *list->add_jobs() = std::move(summary);
    }
    grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
    reactor->Finish(grpc::Status::OK);
    return reactor;
  }

  grpc::ServerUnaryReactor* GetStats(grpc::CallbackServerContext* context,
                                     const v1::GetStatsRequest* request,
                                     v1::Stats* stats) override {
    std::string tenant;
    if (grpc::ServerUnaryReactor* refused = RefuseUnauthorized(context, &tenant)) return refused;
    stats->set_queue_depth(static_cast<uint32_t>(queue_.size()));
    stats->set_queue_capacity(static_cast<uint32_t>(queue_.capacity()));
    stats->set_jobs_accepted(counters_.accepted);
    stats->set_jobs_succeeded(counters_.succeeded);
    stats->set_jobs_failed(counters_.failed);
    stats->set_jobs_cancelled(counters_.cancelled);
    stats->set_jobs_rejected(counters_.rejected);
    stats->set_job_running(counters_.jobs_running > 0);
    stats->set_jobs_running(counters_.jobs_running);
    stats->set_max_input_bytes(options_.max_input_bytes);
    stats->set_calls_active(admission_.total());
    stats->set_calls_refused(counters_.calls_refused);
    stats->set_uploads_timed_out(counters_.uploads_timed_out);
    stats->set_upload_bytes_in_flight(upload_budget_.used());
    stats->set_upload_bytes_limit(upload_budget_.limit());
    stats->set_queued_input_bytes(queued_budget_.used());
    stats->set_queued_input_limit(queued_budget_.limit());
    stats->set_result_bytes_held(result_budget_.used());
    stats->set_result_bytes_limit(result_budget_.limit());
    stats->set_readers_cut_off(counters_.readers_cut_off);
    stats->set_cpu_workers(static_cast<uint32_t>(options_.cpu_workers));
    stats->set_draining(draining_);
    stats->set_jobs_known(static_cast<uint32_t>(registry_.size()));
    stats->set_kept_result_bytes(registry_.kept_bytes());
    stats->set_kept_result_limit(registry_.kept_limit());
    stats->set_results_dropped(registry_.dropped());
    stats->set_watch_calls_active(watch_calls_active_);
    stats->set_retention_seconds(absl::ToDoubleSeconds(registry_.retention()));
    {
      std::lock_guard<std::mutex> lock(gl_mutex_);
      stats->set_gpu_available(!gl_renderer_.empty());
      stats->set_gl_renderer(gl_renderer_);
      stats->set_gl_device(gl_device_);
    }
    const GpuMemoryNow gpu_memory = GpuMemory();
    stats->set_gpu_buffer_bytes(gpu_memory.buffer_bytes);
    stats->set_gpu_buffer_peak_bytes(gpu_memory.peak_buffer_bytes);
    if (gpu_memory.device_total_bytes > 0) {
      stats->set_gpu_device_memory_total_bytes(gpu_memory.device_total_bytes);
    }
    if (gpu_memory.device_exposed) {
      stats->set_gpu_device_memory_available_bytes(gpu_memory.device_available_bytes);
    }
    grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
    reactor->Finish(grpc::Status::OK);
    return reactor;
  }

  grpc::ServerUnaryReactor* GetServerInfo(grpc::CallbackServerContext* context,
                                          const v1::GetServerInfoRequest* request,
                                          v1::ServerInfo* info) override {
    std::string tenant;
    if (grpc::ServerUnaryReactor* refused = RefuseUnauthorized(context, &tenant)) return refused;
    ServerFacts facts;
    {
      std::lock_guard<std::mutex> lock(gl_mutex_);
      facts.gpu_available = !gl_renderer_.empty();
      facts.gl_renderer = gl_renderer_;
      facts.gl_is_software = gl_is_software_;
    }
    facts.max_input_bytes = options_.max_input_bytes;
    facts.queue_capacity = static_cast<uint32_t>(queue_.capacity());
    *info = MakeServerInfo(facts);
    grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
    reactor->Finish(grpc::Status::OK);
    return reactor;
  }

  // Checks what can be checked before any input is read.
  absl::Status CheckSpec(const v1::JobSpec& spec) const {
    if (spec.input_kind() == v1::INPUT_KIND_UNSPECIFIED) {
      return absl::InvalidArgumentError("spec.input_kind is unspecified");
    }
    if (spec.input_kind() != v1::INPUT_KIND_DRACO_MESH &&
        spec.input_kind() != v1::INPUT_KIND_POINTS_F32) {
      return absl::InvalidArgumentError(
          absl::StrCat("spec.input_kind ", static_cast<int>(spec.input_kind()),
                       " is not one this server reads (1: INPUT_KIND_DRACO_MESH, 2: "
                       "INPUT_KIND_POINTS_F32)"));
    }
    if (spec.input_bytes() == 0) return absl::InvalidArgumentError("spec.input_bytes is 0");
    if (spec.input_bytes() > options_.max_input_bytes) {
      return absl::ResourceExhaustedError(absl::StrCat("input of ", spec.input_bytes(),
                                                       " bytes is over this server's limit of ",
                                                       options_.max_input_bytes, " bytes"));
    }
    return CheckSpecIsConsistent(spec);
  }

  // The job's plan at submit (server/job_runner.h PlanJobOnDevice) and its lane, the device
  // policy's (core/plan/device_policy.h LaneFor). A spec that does not plan goes to any
  // worker, which plans it again and reports the error as the job's.
  void PlanAtSubmit(Job& job) const {
    absl::StatusOr<JobPlan> plan = PlanJobOnDevice(job.spec, Device());
    const bool cpu_workers = options_.cpu_workers > 0;
    if (!plan.ok()) {
      job.lane = cpu_workers ? JobLane::kCpu : JobLane::kGl;
      return;
    }
    job.lane = LaneFor(*plan, cpu_workers, job.spec.has_preview()) == WorkerLane::kGl
                   ? JobLane::kGl
                   : JobLane::kCpu;
    job.plan = *std::move(plan);
  }

  // The device as the device policy reads it: the GL context's renderer, the device's free
  // memory as last sampled (after each GL job) where the driver reports it, and the GPU
  // stages' working-set bound.
  DeviceCaps Device() const {
    std::lock_guard<std::mutex> lock(gl_mutex_);
    DeviceCaps caps;
    caps.gpu = !gl_renderer_.empty();
    caps.gpu_is_software = gl_is_software_;
    caps.renderer = gl_renderer_;
    if (device_memory_.device_exposed) caps.free_bytes = device_memory_.device_available_bytes;
#ifdef MLCLUST_HAVE_GPU
    if (gl_limits_ != nullptr) {
      caps.gpu_working_set = [this](PlanStage stage, const JobPlan& plan,
                                    const InputShape& input) -> uint64_t {
        std::lock_guard<std::mutex> lock(gl_mutex_);  // the context may be gone since
        return gl_limits_ != nullptr ? gpu::GpuWorkingSetBound(*gl_limits_, stage, plan, input) : 0;
      };
    }
#endif
    return caps;
  }

  const ServerOptions& options() const { return options_; }
  BoundedJobQueue<Job>& queue() { return queue_; }
  JobRegistry& registry() { return registry_; }
  std::atomic<uint32_t>& watch_calls_active() { return watch_calls_active_; }
  std::atomic<uint64_t>& bytes_out() { return counters_.bytes_out; }
  Counters& counters() { return counters_; }
  CallAdmission& admission() { return admission_; }
  UploadWatchdog& uploads() { return uploads_; }
  MemoryBudget& upload_budget() { return upload_budget_; }
  MemoryBudget& queued_budget() { return queued_budget_; }
  MemoryBudget& result_budget() { return result_budget_; }
  bool draining() const { return draining_; }
  void set_draining() { draining_ = true; }

  // A refused call: counted and logged (never its token). `refused` false: a call that
  // broke the stream's shape (logged as call_failed, not counted as refused).
  void LogRefusal(const std::string& peer, const std::string& tenant, const std::string& label,
                  const absl::Status& status, bool refused = true) {
    if (refused) ++counters_.calls_refused;
    LogEvent(refused ? "call_refused" : "call_failed", "warning")
        .Add("peer", peer)
        .Add("tenant", tenant)
        .Add("label", label)
        .Add("code", CodeName(static_cast<int>(status.code())))
        .Add("message", std::string(status.message()), kLoggedLineBytes)
        .Write(options_.log,
               absl::StrCat(
                   refused ? "refused a call from " : "a call failed from ", LogSafe(peer),
                   label.empty() ? std::string() : absl::StrCat(" (label '", LogSafe(label), "')"),
                   ": ", status.ToString()));
  }

  // A job ended (after running, or while queued): metrics and one log event.
  void JobEnded(const Job& job, const std::string& outcome, absl::Time started_at,
                absl::Time ended_at, int code, const std::string& message, const v1::Done* done) {
    const std::string algorithm = AlgorithmName(job.spec);
    const double queued = absl::ToDoubleSeconds(started_at - job.accepted_at);
    const double running = absl::ToDoubleSeconds(ended_at - started_at);
    job_metrics_.JobEnded(algorithm, outcome, queued, running);
    LogEvent event("job_ended", code == 0                                               ? "info"
                                : code == static_cast<int>(grpc::StatusCode::CANCELLED) ? "warning"
                                                                                        : "error");
    event.Add("job_id", job.id)
        .Add("tenant", job.tenant)
        .Add("peer", job.peer)
        .Add("label", job.spec.label())
        .Add("algorithm", algorithm)
        .Add("input_kind", InputKindText(job.spec))
        .Add("input_bytes", uint64_t{job.spec.input_bytes()})
        .Add("detached", job.spec.detach())
        .Add("outcome", outcome)
        .Add("code", CodeName(code))
        .Add("seconds_queued", queued)
        .Add("seconds_running", running);
    if (done != nullptr) {
      event.Add("levels", uint64_t{done->levels()})
          .Add("triplets", uint64_t{done->triplets()})
          .Add("final_clusters", uint64_t{done->final_clusters()})
          .Add("device", done->device());
    } else {
      event.Add("message", message, kLoggedLineBytes);
    }
    const std::string text =
        done != nullptr
            ? absl::StrCat(job.id, " done in ", absl::FormatDuration(ended_at - started_at), ": ",
                           done->levels(), " levels, ", done->triplets(), " triplets")
            : absl::StrCat(job.id, " ", outcome, " after ",
                           absl::FormatDuration(ended_at - started_at), ": ", message);
    event.Write(options_.log, text);
  }

  // The Prometheus exposition of the server's state (serve --metrics).
  std::string RenderMetrics() {
    std::string out;
    auto metric = [&](const char* name, const char* type, const char* help, auto value) {
      absl::StrAppend(&out, "# HELP ", name, " ", help, "\n# TYPE ", name, " ", type, "\n", name,
                      " ", value, "\n");
    };
    metric("mlclust_queue_depth", "gauge", "Jobs waiting in the queue.", queue_.size());
    metric("mlclust_queue_capacity", "gauge", "Jobs that may wait.", queue_.capacity());
    metric("mlclust_jobs_running", "gauge", "Jobs running now.", counters_.jobs_running.load());
    metric("mlclust_jobs_accepted_total", "counter", "Jobs accepted.", counters_.accepted.load());
    metric("mlclust_jobs_rejected_total", "counter", "Jobs refused before queueing.",
           counters_.rejected.load());
    metric("mlclust_calls_refused_total", "counter", "Calls refused (admission, auth, limits).",
           counters_.calls_refused.load());
    metric("mlclust_calls_active", "gauge", "Run calls in progress.", admission_.total());
    metric("mlclust_uploads_timed_out_total", "counter",
           "Uploads ended for making no progress or going under the minimum rate.",
           counters_.uploads_timed_out.load());
    metric("mlclust_input_bytes_total", "counter", "Input bytes received.",
           counters_.bytes_in.load());
    metric("mlclust_output_bytes_total", "counter", "Event bytes written to clients (serialized).",
           counters_.bytes_out.load());
    metric("mlclust_upload_bytes_in_flight", "gauge", "Bytes of uploads not yet complete.",
           upload_budget_.used());
    metric("mlclust_queued_input_bytes", "gauge", "Inputs of the queued jobs.",
           queued_budget_.used());
    metric("mlclust_unread_event_bytes", "gauge", "Events produced and not yet read (memory).",
           result_budget_.used());
    metric("mlclust_kept_result_bytes", "gauge", "Kept levels of jobs, for Watch (memory).",
           registry_.kept_bytes());
    metric("mlclust_results_dropped_total", "counter", "Ended jobs' results dropped.",
           registry_.dropped());
    metric("mlclust_watch_calls_active", "gauge", "Watch calls in progress.",
           watch_calls_active_.load());
    metric("mlclust_readers_cut_off_total", "counter", "Readers cut off for reading too slowly.",
           counters_.readers_cut_off.load());
    metric("mlclust_cpu_workers", "gauge", "CPU workers beside the GL worker.",
           options_.cpu_workers);
    metric("mlclust_draining", "gauge", "1 while shutting down.", draining_ ? 1 : 0);
#ifdef MLCLUST_HAVE_GPU
    constexpr char kWithGpu[] = "true";
#else
    constexpr char kWithGpu[] = "false";
#endif
    absl::StrAppend(&out,
                    "# HELP mlclust_build_info The server's version and build (value 1).\n"
                    "# TYPE mlclust_build_info gauge\nmlclust_build_info{version=\"",
                    kMlclustVersion, "\",grpc=\"", PrometheusLabel(grpc::Version()),
                    "\",gpu_backend=\"", kWithGpu, "\"} 1\n");
    // Jobs by state (queued, running) and algorithm, from the registry.
    std::map<std::pair<std::string, std::string>, uint64_t> by_state;
    registry_.ForEach([&](const JobRecord& record) {
      const JobState state = record.state();
      if (state == JobState::kQueued || state == JobState::kRunning) {
        ++by_state[{AlgorithmName(record.spec()), JobStateName(state)}];
      }
    });
    absl::StrAppend(&out,
                    "# HELP mlclust_jobs Jobs queued or running, by algorithm and state.\n"
                    "# TYPE mlclust_jobs gauge\n");
    for (const auto& [key, count] : by_state) {
      absl::StrAppend(&out, "mlclust_jobs{algorithm=\"", PrometheusLabel(key.first), "\",state=\"",
                      key.second, "\"} ", count, "\n");
    }
    absl::StrAppend(&out, job_metrics_.Render());
    {
      std::lock_guard<std::mutex> lock(gl_mutex_);
      absl::StrAppend(&out,
                      "# HELP mlclust_device_info The GL device (renderer \"\" without one).\n"
                      "# TYPE mlclust_device_info gauge\n"
                      "mlclust_device_info{renderer=\"",
                      PrometheusLabel(gl_renderer_), "\",software=\"",
                      gl_is_software_ ? "true" : "false", "\"} 1\n",
                      "# HELP mlclust_gpu_available 1 when a GL context is up.\n"
                      "# TYPE mlclust_gpu_available gauge\nmlclust_gpu_available ",
                      gl_renderer_.empty() ? 0 : 1, "\n");
    }
    // GPU memory: our buffers always; the device's only where its driver exposes it.
    const GpuMemoryNow gpu_memory = GpuMemory();
    metric("mlclust_gpu_memory_bytes", "gauge",
           "Storage buffers the server's GL context holds now (bytes).", gpu_memory.buffer_bytes);
    metric("mlclust_gpu_memory_peak_bytes", "gauge",
           "The most the server's GL context held in buffers at once (bytes).",
           gpu_memory.peak_buffer_bytes);
    if (gpu_memory.device_total_bytes > 0) {
      metric("mlclust_gpu_device_memory_total_bytes", "gauge",
             "The GPU's dedicated memory as its driver reports it (GL_NVX_gpu_memory_info).",
             gpu_memory.device_total_bytes);
    }
    if (gpu_memory.device_exposed) {
      metric("mlclust_gpu_device_memory_available_bytes", "gauge",
             "The GPU's free memory as its driver reports it (GL_NVX_gpu_memory_info or "
             "GL_ATI_meminfo), sampled after each GL job.",
             gpu_memory.device_available_bytes);
    }
    return out;
  }

  // A job leaves the queue (to a worker, cancelled, or drained): its input no longer
  // counts as queued.
  void LeftQueue(Job& job) {
    queued_budget_.Release(job.queued_bytes);
    job.queued_bytes = 0;
  }

  // Tells every waiting job its new place in its lane.
  void AnnounceQueuePositions() {
    queue_.ForEachWaiting([](const Job& job, size_t ahead) {
      v1::JobEvent event;
      event.mutable_progress()->set_stage("queued");
      event.mutable_progress()->set_queue_position(static_cast<uint32_t>(ahead));
      event.mutable_progress()->set_message(absl::StrCat(ahead, " jobs ahead"));
      job.events->Emit(std::move(event));
    });
  }

  void SetGl(std::string renderer, std::string device, bool is_software) {
    std::lock_guard<std::mutex> lock(gl_mutex_);
    gl_renderer_ = std::move(renderer);
    gl_device_ = std::move(device);
    gl_is_software_ = is_software;
  }
#ifdef MLCLUST_HAVE_GPU
  // The GL worker's context, whose limits the working-set bound reads (their values only,
  // so on any thread); nullptr before it is destroyed.
  void SetGlLimits(const gpu::GlContext* gl) {
    std::lock_guard<std::mutex> lock(gl_mutex_);
    gl_limits_ = gl;
  }
#endif

  // GPU memory (Stats 33-36, mlclust_gpu_memory_bytes and the device's memory gauges).
  struct GpuMemoryNow {
    uint64_t buffer_bytes = 0;
    uint64_t peak_buffer_bytes = 0;
    bool device_exposed = false;      // the driver reports the device's memory
    uint64_t device_total_bytes = 0;  // 0: not reported (GL_ATI_meminfo, or not exposed)
    uint64_t device_available_bytes = 0;
  };
  GpuMemoryNow GpuMemory() const {
    std::lock_guard<std::mutex> lock(gl_mutex_);
    GpuMemoryNow now = device_memory_;
#ifdef MLCLUST_HAVE_GPU
    if (gpu_memory_gauge_ != nullptr) {
      now.buffer_bytes = gpu_memory_gauge_->buffer_bytes.load(std::memory_order_relaxed);
      now.peak_buffer_bytes = gpu_memory_gauge_->peak_buffer_bytes.load(std::memory_order_relaxed);
    }
#endif
    return now;
  }
#ifdef MLCLUST_HAVE_GPU
  // The GL worker's context: its buffer gauge, and a fresh sample of the device's memory
  // (on the context's thread).
  void SampleGpuMemory(gpu::GlContext& gl) {
    const std::optional<gpu::DeviceMemory> device = gl.QueryDeviceMemory();
    std::lock_guard<std::mutex> lock(gl_mutex_);
    gpu_memory_gauge_ = gl.memory_gauge();
    device_memory_ = GpuMemoryNow();
    if (device.has_value()) {
      device_memory_.device_exposed = true;
      device_memory_.device_total_bytes = device->total_bytes;
      device_memory_.device_available_bytes = device->available_bytes;
    }
  }
#endif

 private:
  const ServerOptions options_;
  BoundedJobQueue<Job> queue_;
  Counters counters_;
  CallAdmission admission_;
  MemoryBudget upload_budget_, queued_budget_, result_budget_;
  JobRegistry registry_;
  UploadWatchdog uploads_;
  std::mutex stores_mutex_;
  std::vector<std::weak_ptr<ResultStore>> stores_;  // every call's, for the shutdown
  JobMetrics job_metrics_;
  std::atomic<uint32_t> watch_calls_active_{0};
  std::atomic<bool> draining_{false};
  mutable std::mutex gl_mutex_;
  std::string gl_renderer_, gl_device_;
  bool gl_is_software_ = false;
  GpuMemoryNow device_memory_;  // the device's part, sampled by the GL worker
#ifdef MLCLUST_HAVE_GPU
  std::shared_ptr<gpu::GpuMemoryGauge> gpu_memory_gauge_;
  const gpu::GlContext* gl_limits_ = nullptr;
#endif
};

RunCall::RunCall(ServiceImpl* service, std::string peer, std::string tenant,
                 const absl::Status& refusal)
    : service_(service),
      peer_(std::move(peer)),
      tenant_(std::move(tenant)),
      admitted_(refusal.ok()),
      channel_(service->NewResultStore(&writer_)) {
  if (!admitted_) {
    Refuse(refusal);
    return;
  }
  service_->uploads().Add(this);
  watched_ = true;
  StartRead(&request_);
}

bool RunCall::LeaveWatchdog() {
  if (!watched_) return true;
  watched_ = false;
  return service_->uploads().Remove(this);
}

std::function<void()> RunCall::EndUpload(const grpc::Status& status, bool* /*rearm*/) {
  {
    std::lock_guard<std::mutex> lock(read_mutex_);
    upload_ended_ = true;
  }
  // A read may be outstanding: Finish is allowed then, and the read ends with ok false.
  return [service = service_, channel = channel_, peer = peer_, tenant = tenant_, status] {
    ++service->counters().uploads_timed_out;
    service->LogRefusal(
        peer, tenant, "",
        absl::Status(static_cast<absl::StatusCode>(status.error_code()), status.error_message()));
    channel->Finish(FailedEvent(status), status);
  };
}

bool RunCall::ReadNext() {
  std::lock_guard<std::mutex> lock(read_mutex_);
  if (upload_ended_) {
    ReleaseUpload();
    return false;
  }
  StartRead(&request_);
  return true;
}

void RunCall::OnDone() {
  LeaveWatchdog();
  channel_->Detach();
  ReleaseUpload();
  if (admitted_) service_->admission().Release(peer_, tenant_);
  // An upload that never became a job (refused, cut short, cancelled) gives its memory
  // back to the system, not only to the allocator.
  const bool held_upload = held_big_upload_ || input_.capacity() >= kTrimAfterBytes;
  delete this;
  if (held_upload) malloc_trim(0);
}

void RunCall::ReleaseUpload() {
  service_->upload_budget().Release(upload_reserved_);
  upload_reserved_ = 0;
}

void RunCall::Fail(const absl::Status& status) {
  LeaveWatchdog();
  ReleaseUpload();
  held_big_upload_ = held_big_upload_ || input_.capacity() >= kTrimAfterBytes;
  std::string().swap(input_);
  const grpc::Status grpc_status = ToGrpc(status);
  channel_->Finish(FailedEvent(grpc_status), grpc_status);
}

void RunCall::Refuse(const absl::Status& status) {
  service_->LogRefusal(peer_, tenant_, have_spec_ ? spec_.label() : std::string(), status);
  Fail(status);
}

void RunCall::FailMalformed(const absl::Status& status) {
  service_->LogRefusal(peer_, tenant_, have_spec_ ? spec_.label() : std::string(), status,
                       /*refused=*/false);
  Fail(status);
}

void RunCall::OnReadDone(bool ok) {
  bool ended_by_watchdog = false;
  {
    std::lock_guard<std::mutex> lock(read_mutex_);
    ended_by_watchdog = upload_ended_;
  }
  if (ended_by_watchdog) {
    Fail(absl::DeadlineExceededError("the upload was ended"));  // its status stands, logged
    return;
  }
  // Every malformed or broken stream below is logged (call_failed).
  if (!ok) {
    // The client closed its side (or the call broke) before the input was complete.
    if (!have_spec_) {
      FailMalformed(absl::InvalidArgumentError("the call ended before a job spec was sent"));
    } else {
      FailMalformed(absl::InvalidArgumentError(absl::StrCat(
          "the input ended after ", input_.size(), " of ", spec_.input_bytes(), " bytes")));
    }
    return;
  }
  if (!have_spec_) {
    if (!request_.has_spec()) {
      FailMalformed(
          absl::InvalidArgumentError("the first message of a call must carry the job spec"));
      return;
    }
    if (absl::Status status = service_->CheckSpec(request_.spec()); !status.ok()) {
      if (status.code() == absl::StatusCode::kResourceExhausted) ++service_->counters().rejected;
      spec_.set_label(request_.spec().label());
      have_spec_ = true;
      Refuse(status);
      return;
    }
    spec_ = request_.spec();
    have_spec_ = true;
    service_->uploads().Progress(this, 0, spec_.input_bytes());  // the spec is progress
    // No reservation from the declared size: the buffer grows as data arrives.
  } else if (request_.has_spec()) {
    FailMalformed(absl::InvalidArgumentError("a second job spec in the same call"));
    return;
  }
  const std::string& chunk = request_.chunk();
  service_->counters().bytes_in += chunk.size();
  if (input_.size() + chunk.size() > spec_.input_bytes()) {
    FailMalformed(absl::InvalidArgumentError(
        absl::StrCat("more input than spec.input_bytes = ", spec_.input_bytes())));
    return;
  }
  // Admission before allocation: the chunk is counted against the uploads in flight
  // before the buffer grows for it.
  if (!chunk.empty()) {
    if (!service_->upload_budget().TryReserve(chunk.size())) {
      Refuse(absl::ResourceExhaustedError(
          absl::StrCat("uploads in progress hold ", service_->upload_budget().used() >> 20,
                       " MiB, the server's limit is ", service_->upload_budget().limit() >> 20,
                       " MiB; try again later")));
      return;
    }
    upload_reserved_ += chunk.size();
    service_->uploads().Progress(this, chunk.size(), spec_.input_bytes());
    if (input_.capacity() < input_.size() + chunk.size()) {
      // Doubling, but never past the declared size.
      input_.reserve(std::min<uint64_t>(
          spec_.input_bytes(),
          std::max<uint64_t>(2 * input_.capacity(), input_.size() + chunk.size())));
    }
    input_.append(chunk);
    input_crc32_ = static_cast<uint32_t>(
        crc32_z(input_crc32_, reinterpret_cast<const Bytef*>(chunk.data()), chunk.size()));
  }
  if (input_.size() == spec_.input_bytes()) {
    if (spec_.has_input_crc32() && spec_.input_crc32() != input_crc32_) {
      FailMalformed(absl::InvalidArgumentError(
          absl::StrCat("input checksum: the ", input_.size(), " bytes received have CRC-32 ",
                       absl::Hex(input_crc32_, absl::kZeroPad8), ", spec.input_crc32 says ",
                       absl::Hex(spec_.input_crc32(), absl::kZeroPad8),
                       " (a chunk was lost, repeated or reordered on the way)")));
      return;
    }
    if (!LeaveWatchdog()) {  // ended by the watchdog as the last chunk came
      ReleaseUpload();
      return;
    }
    Submit();
    return;
  }
  ReadNext();
}

void RunCall::Submit() {
  absl::StatusOr<std::string> new_id = RandomJobId();
  if (!new_id.ok()) {
    Refuse(new_id.status());
    return;
  }
  auto job = std::make_shared<Job>();
  job->id = *std::move(new_id);
  job->spec = std::move(spec_);
  job->input = std::move(input_);
  job->events = channel_;
  job->accepted_at = absl::Now();
  job->peer = peer_;
  service_->PlanAtSubmit(*job);
  job->tenant = tenant_;
  const std::string id = job->id;
  const std::string label = job->spec.label();
  const uint64_t bytes = job->input.size();
  const bool detach = job->spec.detach();
  // The input moves from the uploads in flight to the queued inputs.
  ReleaseUpload();
  // What the payload's header contradicts in the spec is refused before Accepted.
  if (absl::Status status = CheckPayloadAgainstSpec(job->spec, job->input); !status.ok()) {
    spec_.set_label(label);
    Refuse(status);
    return;
  }
  const uint32_t per_tenant = service_->options().max_jobs_per_tenant;
  if (per_tenant > 0 && service_->registry().ActiveJobs(tenant_) >= per_tenant) {
    ++service_->counters().rejected;
    spec_.set_label(label);
    Refuse(absl::ResourceExhaustedError(absl::StrCat(
        tenant_.empty() ? std::string("this server") : absl::StrCat("tenant '", tenant_, "'"),
        " has ", per_tenant, " jobs queued or running, its limit; try again later")));
    return;
  }
  if (!service_->queued_budget().TryReserve(bytes)) {
    ++service_->counters().rejected;
    spec_.set_label(label);
    Refuse(absl::ResourceExhaustedError(
        absl::StrCat("the queued jobs' inputs take ", service_->queued_budget().used() >> 20,
                     " MiB; with this one's ", bytes >> 20, " MiB they would exceed the limit of ",
                     service_->queued_budget().limit() >> 20, " MiB; try again later")));
    return;
  }
  job->queued_bytes = bytes;
  // An attached job's record keeps its levels: a reader cut off releases the job to it
  // (the job runs on; the call's end says to watch it) instead of cancelling it.
  if (!detach) channel_->KeepJobOnCutOff(id);
  // The job's entry in the registry, which keeps its levels for Watch: a detached job's
  // events go to it, an attached job's to this call with a copy to it.
  auto record = std::make_shared<JobRecord>(&service_->registry(), id, tenant_, job->spec, detach,
                                            service_->options().max_event_bytes);
  record->set_job(job);
  record->set_owner(peer_);
  job->record = record;
  job->events = detach ? std::shared_ptr<EventChannel>(record)
                       : std::make_shared<RecordingChannel>(channel_, record);
  service_->registry().Add(record);
  job_ = job;
  v1::Accepted described;  // how element ids relate to the input (server/job_runner.h)
  DescribeInput(job->spec, job->input, described);
  record->set_accepted(described);
  std::shared_ptr<Job> queued = job;
  v1::JobEvent accepted_event;
  // The Accepted event is queued while the queue's lock is held, so it is always the
  // first event even if a worker picks the job up at once.
  absl::StatusOr<size_t> ahead = service_->queue().Push(
      std::move(queued), static_cast<unsigned>(job->lane), [&](size_t jobs_ahead) {
        v1::Accepted* accepted = accepted_event.mutable_accepted();
        *accepted = described;
        accepted->set_job_id(id);
        accepted->set_queue_position(static_cast<uint32_t>(jobs_ahead));
        accepted->set_input_bytes(bytes);
        accepted->set_detached(detach);
        accepted->set_tenant(tenant_);
        accepted->set_retention_seconds(
            absl::ToDoubleSeconds(service_->options().result_retention));
        if (!detach) channel_->Emit(accepted_event);
        ++service_->counters().accepted;  // before a worker can finish it
      });
  if (!ahead.ok()) {
    service_->registry().Remove(id);
    service_->LeftQueue(*job);
    ++service_->counters().rejected;
    const absl::Status status =
        ahead.status().code() == absl::StatusCode::kFailedPrecondition
            ? absl::UnavailableError(
                  "the server is shutting down; submit the job to another server or try again "
                  "later")
            : ahead.status();
    spec_.set_label(label);
    Refuse(status);
    return;
  }
  LogEvent("job_accepted")
      .Add("job_id", id)
      .Add("tenant", tenant_)
      .Add("peer", peer_)
      .Add("label", label)
      .Add("algorithm", AlgorithmName(job->spec))
      .Add("input_kind", InputKindText(job->spec))
      .Add("input_bytes", uint64_t{bytes})
      .Add("worker", job->lane == JobLane::kGl ? "gl" : "cpu")
      .Add("jobs_ahead", uint64_t{*ahead})
      .Add("detached", detach)
      .Write(service_->options().log,
             absl::StrCat(id, " accepted from ", LogSafe(peer_), " (label '", LogSafe(label), "', ",
                          bytes, " bytes, ",
                          job->lane == JobLane::kGl ? "GL worker, " : "CPU workers, ", *ahead,
                          " ahead", detach ? ", detached" : "", ")"));
  // A detached job's call ends here; the job runs on and Watch reads its levels.
  if (detach) channel_->Finish(std::move(accepted_event), grpc::Status::OK);
}

void RunCall::OnCancel() {
  channel_->OnCancel();
  std::shared_ptr<Job> job = job_.lock();
  // A detached job does not depend on the call that submitted it.
  if (job != nullptr && !job->spec.detach()) {
    if (service_->queue().Remove(job.get())) {
      service_->LeftQueue(*job);
      ++service_->counters().cancelled;
      job->record->MarkEnded(grpc::Status(grpc::StatusCode::CANCELLED, "cancelled while queued"));
      service_->JobEnded(*job, "cancelled", absl::Now(), absl::Now(), grpc::StatusCode::CANCELLED,
                         "cancelled while queued", nullptr);
    }
  }
}

// The reactor of one Watch call: writes the job's kept events one at a time from its
// record, each when the previous write is done, and waits (registered with the record)
// when it has read everything so far. The job never waits for it. Admitted like a Run call
// (the same limits); the event being written counts in the server's memory for unread
// events (a watcher that does not fit is cut off), and a client that takes no event for
// the watch idle timeout is cut off: its slot is given back at once, the call ends with
// RESOURCE_EXHAUSTED when the client reads again, and is cancelled after one more timeout.
class WatchCall : public grpc::ServerWriteReactor<v1::JobEvent>, public WatchedUpload {
 public:
  WatchCall(ServiceImpl* service, grpc::CallbackServerContext* context,
            absl::StatusOr<std::shared_ptr<JobRecord>> record, const v1::WatchRequest& request,
            std::string peer, std::string tenant, bool admitted)
      : service_(service),
        context_(context),
        peer_(std::move(peer)),
        tenant_(std::move(tenant)),
        slot_held_(admitted),
        waker_(std::make_shared<Waker>(this)) {
    ++service_->watch_calls_active();
    if (!record.ok()) {
      finished_ = true;  // before Finish: OnDone may delete this at once
      Finish(ToGrpc(record.status()));
      return;
    }
    record_ = *std::move(record);
    cursor_ = WatchCursorFor(request.from_level(), request.resume());
    Wake();
  }

  void OnWriteDone(bool ok) override {
    service_->uploads().Remove(this);
    {
      std::lock_guard<std::mutex> lock(waker_->mutex);
      write_in_flight_ = false;
      ReleaseReservedLocked();
      if (!ok) cancelled_ = true;
    }
    Wake();
  }

  void OnCancel() override {
    {
      std::lock_guard<std::mutex> lock(waker_->mutex);
      cancelled_ = true;
    }
    Wake();
  }

  void OnDone() override {
    service_->uploads().Remove(this);
    {
      std::lock_guard<std::mutex> lock(waker_->mutex);
      waker_->call = nullptr;
      ReleaseReservedLocked();
      ReleaseSlotLocked();
    }
    --service_->watch_calls_active();
    delete this;
  }

  // The watchdog: the write in flight was not taken for the watch idle timeout.
  std::function<void()> EndUpload(const grpc::Status& status, bool* rearm) override {
    std::lock_guard<std::mutex> lock(waker_->mutex);
    if (cut_off_.has_value()) {
      // Cut off one timeout ago and still not reading: cancelled, its memory freed.
      context_->TryCancel();
      return [] {};
    }
    const grpc::Status cut_off(
        status.error_code(),
        absl::StrCat(status.error_message(), "; the watch was cut off (the job runs on: watch ",
                     record_->id(), " again, with --from-level or resume, to read on)"));
    cut_off_ = cut_off;
    *rearm = true;
    cursor_ = WatchCursor();  // the labels it held go
    ReleaseSlotLocked();
    return [service = service_, cut_off] {
      ++service->counters().readers_cut_off;
      LogLine(service->options().log, "a watcher was cut off: ", cut_off.error_message());
    };
  }

 private:
  // Through a copy of the waker: the call may end (and be deleted) inside.
  void Wake() {
    std::shared_ptr<Waker> waker = waker_;
    waker->Wake();
  }

  // Registered with the record while the call waits; outlives the call (the record holds
  // it weakly, a wake may be on its way as the call ends).
  struct Waker : RecordWaiter {
    explicit Waker(WatchCall* c) : call(c) {}
    void Wake() override {
      std::unique_lock<std::mutex> lock(mutex);
      if (call != nullptr) call->Pump(lock);
    }
    std::mutex mutex;
    WatchCall* call;
  };

  void ReleaseReservedLocked() {
    service_->result_budget().Release(reserved_bytes_);
    reserved_bytes_ = 0;
  }
  void ReleaseSlotLocked() {
    if (!slot_held_) return;
    slot_held_ = false;
    service_->admission().Release(peer_, tenant_);
  }

  // With the waker's lock held: starts the next write or ends the call. The lock is
  // released before calling into gRPC; the call cannot end in between (only Finish, here,
  // ends it, and a write in flight keeps it).
  void Pump(std::unique_lock<std::mutex>& lock) {
    if (finished_ || write_in_flight_) return;
    if (cut_off_.has_value()) {
      finished_ = true;
      const grpc::Status status = *cut_off_;
      lock.unlock();
      Finish(status);
      return;
    }
    if (cancelled_) {
      finished_ = true;
      lock.unlock();
      Finish(grpc::Status(grpc::StatusCode::CANCELLED, "the watch was cancelled"));
      return;
    }
    grpc::Status status;
    switch (record_->NextEvent(cursor_, event_, status, waker_)) {
      case JobRecord::Next::kEvent: {
        // The event in flight counts in the server's memory for unread events: the
        // message and its serialized copy in gRPC's buffers until the write is done.
        const uint64_t bytes = event_.SpaceUsedLong() + event_.ByteSizeLong();
        if (!service_->result_budget().TryReserve(bytes)) {
          finished_ = true;
          ++service_->counters().readers_cut_off;
          const grpc::Status full(
              grpc::StatusCode::RESOURCE_EXHAUSTED,
              absl::StrCat("the server's memory for unread events (",
                           service_->result_budget().limit() >> 20,
                           " MiB) is full; the watch was cut off (the job runs on: watch ",
                           record_->id(), " again later, with --from-level or resume)"));
          lock.unlock();
          Finish(full);
          return;
        }
        reserved_bytes_ = bytes;
        write_in_flight_ = true;
        service_->bytes_out() += event_.ByteSizeLong();
        lock.unlock();
        service_->uploads().AddWrite(this);
        StartWrite(&event_);
        return;
      }
      case JobRecord::Next::kEnd:
        finished_ = true;
        lock.unlock();
        Finish(status);
        return;
      case JobRecord::Next::kWait:
        return;
    }
  }

  ServiceImpl* service_;
  grpc::CallbackServerContext* const context_;  // valid until OnDone
  const std::string peer_, tenant_;
  bool slot_held_;                       // an admission slot (given back once)
  uint64_t reserved_bytes_ = 0;          // of the result budget, for the event in flight
  std::optional<grpc::Status> cut_off_;  // set by the watchdog
  std::shared_ptr<Waker> waker_;
  std::shared_ptr<JobRecord> record_;
  WatchCursor cursor_;
  v1::JobEvent event_;
  bool write_in_flight_ = false;
  bool finished_ = false;
  bool cancelled_ = false;
};

grpc::ServerWriteReactor<v1::JobEvent>* ServiceImpl::Watch(grpc::CallbackServerContext* context,
                                                           const v1::WatchRequest* request) {
  // The same admission as Run calls, before anything is allocated for the call.
  std::string peer = context->peer();
  absl::StatusOr<std::string> tenant = Authorize(context);
  const absl::Status admitted =
      !tenant.ok() ? tenant.status()
      : draining_  ? absl::UnavailableError("the server is shutting down; try again later")
                   : admission_.Admit(peer, *tenant);
  if (!admitted.ok()) {
    LogRefusal(peer, tenant.value_or(""), "", admitted);
    return new WatchCall(this, context, admitted, *request, std::move(peer), "", false);
  }
  absl::StatusOr<std::shared_ptr<JobRecord>> record = registry_.Find(request->job_id(), *tenant);
  return new WatchCall(this, context, std::move(record), *request, std::move(peer),
                       *std::move(tenant), true);
}

}  // namespace

class ServerImpl {
 public:
  explicit ServerImpl(const ServerOptions& options) : service_(options) {}

  absl::Status Start() {
    const ServerOptions& options = service_.options();
    if (absl::Status valid = ValidateOptions(options); !valid.ok()) return valid;
    JsonLogs() = options.log_json;
    // The GL worker owns the GL context: it creates it on its own thread and reports back.
    std::promise<absl::Status> started;
    std::future<absl::Status> started_future = started.get_future();
    gl_worker_ = std::thread([this, &started] { GlWorkerMain(started); });
    if (absl::Status status = started_future.get(); !status.ok()) {
      service_.queue().Stop();
      gl_worker_.join();
      return status;
    }
    // Ended jobs past the retention time are dropped even when nobody asks.
    sweeper_ = std::thread([this] {
      std::unique_lock<std::mutex> lock(sweeper_mutex_);
      while (!sweeper_stop_) {
        sweeper_wake_.wait_for(lock, std::chrono::seconds(1));
        lock.unlock();
        service_.registry().Sweep();
        lock.lock();
      }
    });
    service_.uploads().Start();
    for (size_t i = 0; i < options.cpu_workers; ++i) {
      cpu_workers_.emplace_back([this] {
        JobRunnerContext context;  // no GL: the jobs planned for the CPU (the lane)
        RunJobs(1u << static_cast<unsigned>(JobLane::kCpu), context);
      });
    }

    grpc::EnableDefaultHealthCheckService(true);
    grpc::reflection::InitProtoReflectionServerBuilderPlugin();
    grpc::ServerBuilder builder;
    if (!options.listen_address.empty()) {
      absl::StatusOr<std::shared_ptr<grpc::ServerCredentials>> credentials = Credentials(options);
      if (!credentials.ok()) {
        StopWorkers();
        return credentials.status();
      }
      builder.AddListeningPort(options.listen_address, *credentials, &port_);
    }
    builder.RegisterService(&service_);
    builder.SetMaxReceiveMessageSize(kMaxReceiveMessageBytes);
    builder.SetMaxSendMessageSize(-1);
    // A port already in use is refused: no second server silently shares it.
    builder.AddChannelArgument(GRPC_ARG_ALLOW_REUSEPORT, 0);
    // Connections: a client that connects and never speaks gRPC is dropped after the
    // handshake timeout; idle connections are closed; keepalive pings every minute keep
    // long streams alive through load balancers and find dead peers, and clients may ping
    // as often as every 10 s, with or without calls.
    builder.AddChannelArgument(GRPC_ARG_SERVER_HANDSHAKE_TIMEOUT_MS, 10'000);
    builder.AddChannelArgument(GRPC_ARG_MAX_CONNECTION_IDLE_MS, 5 * 60'000);
    builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIME_MS, 60'000);
    builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, 20'000);
    builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 1);
    builder.AddChannelArgument(GRPC_ARG_HTTP2_MIN_RECV_PING_INTERVAL_WITHOUT_DATA_MS, 10'000);
    server_ = builder.BuildAndStart();
    if (server_ == nullptr || (!options.listen_address.empty() && port_ == 0)) {
      StopWorkers();
      return absl::UnavailableError(absl::StrCat("cannot listen on '", options.listen_address,
                                                 "' (in use, or not an address of this host)"));
    }
    if (!options.metrics_address.empty()) {
      // GET /ready: what the health service's mlclust.v1.Clustering says (SetOnFull below).
      absl::StatusOr<std::unique_ptr<MetricsHttpServer>> metrics = MetricsHttpServer::Start(
          options.metrics_address, [this] { return service_.RenderMetrics(); },
          [this]() -> std::string {
            if (service_.draining()) return "not ready: draining";
            if (service_.queue().size() >= service_.queue().capacity()) {
              return "not ready: the job queue is full";
            }
            return "";
          });
      if (!metrics.ok()) {
        server_->Shutdown();
        StopWorkers();
        return metrics.status();
      }
      metrics_ = *std::move(metrics);
      LogLine(options.log, "metrics on http://",
              options.metrics_address.substr(0, options.metrics_address.rfind(':')), ":",
              metrics_->port(), "/metrics");
    }
    // The device is ready (the GL worker has started): serving from here on. Readiness
    // (mlclust.v1.Clustering; docker/k8s) follows the server's own state: NOT_SERVING while
    // the queue is full (new jobs are refused at once: a load balancer or a client resolving
    // the replicas sends them elsewhere) and from the drain on; the overall service ("",
    // liveness) stays SERVING until the drain.
    service_.queue().SetOnFull([this](bool full) {
      if (!service_.draining()) {
        server_->GetHealthCheckService()->SetServingStatus(kServiceName, !full);
      }
    });
    server_->GetHealthCheckService()->SetServingStatus(kServiceName, true);
    LogLine(
        options.log, "serving ", kServiceName,
        options.listen_address.empty() ? std::string(" in-process")
                                       : absl::StrCat(" on port ", port_),
        "; queue capacity ", options.queue_capacity, "; CPU workers ", options.cpu_workers,
        "; GL: ",
        gl_renderer_.empty() ? absl::StrCat("none (", gl_unavailable_reason_, ")") : gl_renderer_);
    if (!options.listen_address.empty() && !IsLoopback(options.listen_address) &&
        options.auth_tokens.empty()) {
      LogLine(options.log, "warning: listening on ", options.listen_address,
              options.tls_cert_pem.empty() ? " without TLS or authentication"
                                           : " with TLS but without tokens",
              ": anyone who can reach it can submit jobs");
    }
    if (!options.tls_cert_pem.empty()) {
      LogLine(options.log, "TLS on; client certificates ",
              options.tls_client_ca_pem.empty() ? "not requested" : "required", "; bearer tokens ",
              options.auth_tokens.empty() ? std::string("off")
                                          : absl::StrCat("on (", options.auth_tokens.size(), ")"));
    }
    return absl::OkStatus();
  }

  // Options a server cannot run with safely, refused before anything starts.
  static absl::Status ValidateOptions(const ServerOptions& options) {
    if (options.upload_idle_timeout <= absl::ZeroDuration() ||
        options.upload_idle_timeout > absl::Hours(1)) {
      return absl::InvalidArgumentError(
          absl::StrCat("the upload idle timeout must be over 0 and at most 1 hour, not ",
                       absl::FormatDuration(options.upload_idle_timeout)));
    }
    if (options.watch_idle_timeout <= absl::ZeroDuration() ||
        options.watch_idle_timeout > absl::Hours(1)) {
      return absl::InvalidArgumentError(
          absl::StrCat("the watch idle timeout must be over 0 and at most 1 hour, not ",
                       absl::FormatDuration(options.watch_idle_timeout)));
    }
    // /metrics is plain HTTP without a token: where tokens are on it stays on loopback
    // (scraped by a sidecar or through a port forward) unless the operator says otherwise.
    if (!options.auth_tokens.empty() && !options.metrics_address.empty() &&
        !options.metrics_allow_remote && !IsLoopback(options.metrics_address)) {
      return absl::InvalidArgumentError(absl::StrCat(
          "--metrics ", options.metrics_address,
          ": metrics are plain HTTP without a token; with --auth-token-file they are served on "
          "loopback only (127.0.0.1:PORT or [::1]:PORT), unless --metrics-allow-remote"));
    }
    if (options.upload_min_bytes_per_second > (uint64_t{1} << 30)) {
      return absl::InvalidArgumentError(
          absl::StrCat("the minimum upload rate must be at most 1 GiB/s, not ",
                       options.upload_min_bytes_per_second, " bytes/s"));
    }
    return absl::OkStatus();
  }

  // The listener's credentials: plaintext, or TLS (optionally requiring client
  // certificates) with the token check.
  static absl::StatusOr<std::shared_ptr<grpc::ServerCredentials>> Credentials(
      const ServerOptions& options) {
    if (options.tls_cert_pem.empty() != options.tls_key_pem.empty()) {
      return absl::InvalidArgumentError("TLS needs both a certificate and its key");
    }
    if (options.tls_cert_pem.empty()) {
      if (!options.auth_tokens.empty()) {
        return absl::InvalidArgumentError(
            "bearer tokens need TLS (--tls-cert and --tls-key): a token is never accepted in "
            "plaintext");
      }
      if (!options.tls_client_ca_pem.empty()) {
        return absl::InvalidArgumentError("--tls-client-ca needs --tls-cert and --tls-key");
      }
      return grpc::InsecureServerCredentials();
    }
    grpc::SslServerCredentialsOptions ssl(
        options.tls_client_ca_pem.empty()
            ? GRPC_SSL_DONT_REQUEST_CLIENT_CERTIFICATE
            : GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY);
    ssl.pem_root_certs = options.tls_client_ca_pem;
    ssl.pem_key_cert_pairs.push_back({options.tls_key_pem, options.tls_cert_pem});
    std::shared_ptr<grpc::ServerCredentials> credentials = grpc::SslServerCredentials(ssl);
    if (!options.auth_tokens.empty()) {
      credentials->SetAuthMetadataProcessor(MakeTokenProcessor(options.auth_tokens));
    }
    return credentials;
  }

  void Shutdown() {
    std::lock_guard<std::mutex> lock(shutdown_mutex_);
    if (shut_down_) return;
    shut_down_ = true;
    const ServerOptions& options = service_.options();
    // One line when the drain starts (SIGTERM, SIGINT or Shutdown()), in either format.
    LogEvent("shutdown", "warning")
        .Add("queued", uint64_t{service_.queue().size()})
        .Add("running", uint64_t{service_.counters().jobs_running.load()})
        .Add("drain_seconds", absl::ToDoubleSeconds(options.drain_time))
        .Write(
            options.log,
            absl::StrCat("shutting down: not serving; ", service_.queue().size(),
                         " queued jobs end now, ", service_.counters().jobs_running.load(),
                         " running may finish within ", absl::FormatDuration(options.drain_time)));
    // 1. Not serving, at once: health checks and new calls see it.
    service_.set_draining();
    if (server_ != nullptr) {
      server_->GetHealthCheckService()->SetServingStatus(kServiceName, false);
      server_->GetHealthCheckService()->SetServingStatus(false);
    }
    // 2. Queued jobs end now, with a final Failed UNAVAILABLE.
    std::vector<std::shared_ptr<Job>> queued = service_.queue().StopAndTakeAll();
    if (server_ != nullptr) {
      // Again, now that the queue is stopped: a queue that had room again just before the
      // drain may have set SERVING after step 1 (SetOnFull).
      server_->GetHealthCheckService()->SetServingStatus(kServiceName, false);
    }
    for (const std::shared_ptr<Job>& job : queued) {
      service_.LeftQueue(*job);
      ++service_.counters().cancelled;
      const grpc::Status unavailable(grpc::StatusCode::UNAVAILABLE,
                                     "the server is shutting down and the job had not started; "
                                     "submit it to another server or try again later");
      job->events->Abort(unavailable);
      job->record->MarkEnded(unavailable);
      service_.JobEnded(*job, JobStateName(job->record->state()), absl::Now(), absl::Now(),
                        unavailable.error_code(), "not started: the server is shutting down",
                        nullptr);
    }
    // 3. Running jobs may finish within the drain time; then they are cancelled.
    {
      std::unique_lock<std::mutex> running_lock(running_mutex_);
      if (!running_.empty()) {
        LogLine(options.log, "draining: ", running_.size(), " running jobs, up to ",
                absl::FormatDuration(options.drain_time));
      }
      running_done_.wait_for(running_lock, absl::ToChronoNanoseconds(options.drain_time),
                             [&] { return running_.empty(); });
      for (const std::shared_ptr<Job>& job : running_) {
        job->events->Abort(
            grpc::Status(grpc::StatusCode::UNAVAILABLE,
                         "the server is shutting down and the drain time ran out; the job "
                         "was cancelled"));
        LogLine(options.log, job->id, " cancelled: the drain time ran out");
      }
    }
    StopWorkers();
    metrics_.reset();
    service_.FlushCallsForShutdown();
    if (server_ != nullptr) {
      // Calls still open (clients that stopped reading) are cancelled after 2 s.
      server_->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(2));
      server_->Wait();
    }
    shutdown_done_.notify_all();
  }

  void Wait() {
    std::unique_lock<std::mutex> lock(shutdown_mutex_);
    shutdown_done_.wait(lock, [&] { return shut_down_; });
  }

  int port() const { return port_; }
  int metrics_port() const { return metrics_ != nullptr ? metrics_->port() : 0; }
  std::shared_ptr<grpc::Channel> InProcessChannel() {
    grpc::ChannelArguments arguments;
    arguments.SetMaxReceiveMessageSize(-1);
    return server_->InProcessChannel(arguments);
  }
  std::string gl_renderer() const { return gl_renderer_; }
  std::string gl_unavailable_reason() const { return gl_unavailable_reason_; }

 private:
  void StopWorkers() {
    service_.queue().Stop();
    service_.uploads().Stop();
    if (sweeper_.joinable()) {
      {
        std::lock_guard<std::mutex> lock(sweeper_mutex_);
        sweeper_stop_ = true;
      }
      sweeper_wake_.notify_all();
      sweeper_.join();
    }
    if (gl_worker_.joinable()) gl_worker_.join();
    for (std::thread& worker : cpu_workers_) worker.join();
    cpu_workers_.clear();
  }

  void GlWorkerMain(std::promise<absl::Status>& started) {
    const ServerOptions& options = service_.options();
    JobRunnerContext context;
#ifdef MLCLUST_HAVE_GPU
    std::unique_ptr<gpu::GlContext> gl;
    std::unique_ptr<gpu::GlDeviceStages> stages;
    if (options.gpu != GpuMode::kOff) {
      absl::StatusOr<std::unique_ptr<gpu::GlContext>> created = gpu::GlContext::Create({});
      if (created.ok()) {
        gl = *std::move(created);
        context.gl = gl.get();
        stages = std::make_unique<gpu::GlDeviceStages>(*gl);
        context.devices = stages.get();
        gl_renderer_ = gl->renderer();
        service_.SetGl(gl->renderer(), gl->device_description(), gl->is_software());
        service_.SetGlLimits(gl.get());
        service_.SampleGpuMemory(*gl);
        LogLine(options.log, "GL context: ", gl->renderer(), " (", gl->version(), ", ",
                gl->device_description(), ")");
      } else {
        gl_unavailable_reason_ = std::string(created.status().message());
      }
    } else {
      gl_unavailable_reason_ = "disabled by the server's options";
    }
#else
    gl_unavailable_reason_ = "built without MLCLUST_WITH_GPU";
#endif
    if (options.gpu == GpuMode::kOn && gl_renderer_.empty()) {
      started.set_value(absl::UnavailableError(absl::StrCat(
          "a GPU was required but no GL context could be created: ", gl_unavailable_reason_)));
      return;
    }
    started.set_value(absl::OkStatus());
    // Without CPU workers the GL worker runs every job.
    const unsigned lanes = options.cpu_workers == 0 ? BoundedJobQueue<Job>::kAllLanes
                                                    : 1u << static_cast<unsigned>(JobLane::kGl);
    RunJobs(lanes, context);
#ifdef MLCLUST_HAVE_GPU
    service_.SetGlLimits(nullptr);  // the context goes with this function
#endif
  }

  // A worker's loop: runs the jobs of `lanes` until the queue stops.
  void RunJobs(unsigned lanes, const JobRunnerContext& context) {
    Counters& counters = service_.counters();
    while (std::shared_ptr<Job> job = service_.queue().Pop(lanes)) {
      service_.LeftQueue(*job);
      service_.AnnounceQueuePositions();
      if (job->events->cancelled()) {
        ++counters.cancelled;
        job->record->MarkEnded(grpc::Status(grpc::StatusCode::CANCELLED, "cancelled while queued"));
        service_.JobEnded(*job, "cancelled", absl::Now(), absl::Now(), grpc::StatusCode::CANCELLED,
                          "cancelled while queued", nullptr);
        continue;
      }
      job->record->MarkRunning();
      {
        std::lock_guard<std::mutex> lock(running_mutex_);
        running_.push_back(job);
      }
      ++counters.jobs_running;
      const absl::Time started_at = absl::Now();
      JobRunnerContext job_context = context;
      job_context.device = service_.Device();  // its free memory as last sampled
      absl::StatusOr<JobOutcome> outcome = RunJob(*job, job_context);
      const absl::Time ended_at = absl::Now();
      if (outcome.ok()) {
        v1::JobEvent event;
        *event.mutable_done() = outcome->done;
        event.mutable_done()->set_seconds_queued(
            absl::ToDoubleSeconds(started_at - job->accepted_at));
        event.mutable_done()->set_seconds_running(absl::ToDoubleSeconds(ended_at - started_at));
        ++counters.succeeded;  // before Finish, so a client that saw Done sees it counted
        const v1::Done done = event.done();
        job->events->Finish(std::move(event), grpc::Status::OK);
        job->record->MarkEnded(grpc::Status::OK, &done);
        service_.JobEnded(*job, JobStateName(job->record->state()), started_at, ended_at, 0, "",
                          &done);
      } else {
        const grpc::Status status = ToGrpc(outcome.status());
        ++(outcome.status().code() == absl::StatusCode::kCancelled ? counters.cancelled
                                                                   : counters.failed);
        job->events->Finish(FailedEvent(status), status);
        job->record->MarkEnded(status);
        // The record's state: the first ending wins (a cut-off's RESOURCE_EXHAUSTED, a
        // Cancel call's CANCELLED) over the runner's CANCELLED that followed it.
        service_.JobEnded(*job, JobStateName(job->record->state()), started_at, ended_at,
                          status.error_code(), outcome.status().ToString(), nullptr);
      }
#ifdef MLCLUST_HAVE_GPU
      if (context.gl != nullptr) service_.SampleGpuMemory(*context.gl);
#endif
      const std::string id = job->id;
      // The input and anything else the job holds go now, not when the call ends.
      std::string().swap(job->input);
      --counters.jobs_running;
      bool idle = false;
      {
        std::lock_guard<std::mutex> lock(running_mutex_);
        std::erase(running_, job);
        idle = running_.empty();
        running_done_.notify_all();
      }
      job.reset();
      // Memory back to the system after a burst, not kept at the largest job's level.
      if (idle && service_.queue().size() == 0) malloc_trim(0);
    }
  }

  ServiceImpl service_;
  std::unique_ptr<grpc::Server> server_;
  std::unique_ptr<MetricsHttpServer> metrics_;
  std::thread gl_worker_, sweeper_;
  std::mutex sweeper_mutex_;
  std::condition_variable sweeper_wake_;
  bool sweeper_stop_ = false;
  std::vector<std::thread> cpu_workers_;
  int port_ = 0;
  std::string gl_renderer_, gl_unavailable_reason_;
  std::mutex running_mutex_;
  std::condition_variable running_done_;
  std::vector<std::shared_ptr<Job>> running_;
  std::mutex shutdown_mutex_;
  std::condition_variable shutdown_done_;
  bool shut_down_ = false;
};

absl::StatusOr<std::unique_ptr<Server>> Server::Start(const ServerOptions& options) {
  auto impl = std::make_unique<ServerImpl>(options);
  if (absl::Status status = impl->Start(); !status.ok()) return status;
  return std::unique_ptr<Server>(new Server(std::move(impl)));
}

Server::Server(std::unique_ptr<ServerImpl> impl) : impl_(std::move(impl)) {}
Server::~Server() { Shutdown(); }
int Server::port() const { return impl_->port(); }
int Server::metrics_port() const { return impl_->metrics_port(); }
std::shared_ptr<grpc::Channel> Server::InProcessChannel() { return impl_->InProcessChannel(); }
std::string Server::gl_renderer() const { return impl_->gl_renderer(); }
std::string Server::gl_unavailable_reason() const { return impl_->gl_unavailable_reason(); }
void Server::Wait() { impl_->Wait(); }
void Server::Shutdown() { impl_->Shutdown(); }

}  // namespace mlclust::server
