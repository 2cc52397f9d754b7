#include "server/server.h"

#include <atomic>
#include <condition_variable>
#include <deque>
#include <future>
#include <mutex>
#include <thread>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/time/clock.h"
#include "grpcpp/ext/proto_server_reflection_plugin.h"
#include "grpcpp/grpcpp.h"
#include "grpcpp/health_check_service_interface.h"
#include "mlclust/v1/mlclust.grpc.pb.h"
#include "server/job.h"
#include "server/job_queue.h"
#include "server/job_runner.h"
#include "server/log.h"
#include "server/memory_budget.h"
#include "server/result_store.h"
#ifdef MLCLUST_HAVE_GPU
#include "gpu/gl_context.h"
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

struct Counters {
  std::atomic<uint64_t> accepted{0}, succeeded{0}, failed{0}, cancelled{0}, rejected{0},
      readers_cut_off{0};
  std::atomic<bool> job_running{false};
};

class ServiceImpl;

// The reactor of one Run call: reads the spec and the input chunks, submits the job,
// then writes the job's events through its ResultStore.
class RunCall : public grpc::ServerBidiReactor<v1::RunRequest, v1::JobEvent> {
 public:
  explicit RunCall(ServiceImpl* service);

  void OnReadDone(bool ok) override;
  void OnWriteDone(bool ok) override { channel_->OnWriteDone(ok); }
  void OnCancel() override;
  void OnDone() override {
    channel_->Detach();
    delete this;
  }

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
  void Submit();

  ServiceImpl* service_;
  Writer writer_{this};
  std::shared_ptr<ResultStore> channel_;
  v1::RunRequest request_;
  v1::JobSpec spec_;
  bool have_spec_ = false;
  std::string input_;
  std::weak_ptr<Job> job_;
};

class ServiceImpl final : public v1::Clustering::CallbackService {
 public:
  ServiceImpl(const ServerOptions& options)
      : options_(options),
        queue_(options.queue_capacity),
        result_budget_(options.result_server_budget_bytes) {}

  // A new job's store of events, writing to `writer`.
  std::shared_ptr<ResultStore> NewResultStore(EventWriter* writer) {
    ResultStoreOptions store_options;
    store_options.job_budget_bytes = options_.result_job_budget_bytes;
    store_options.max_event_bytes = options_.max_event_bytes;
    store_options.on_cut_off = [this](const grpc::Status& status) {
      ++counters_.readers_cut_off;
      LogLine(options_.log, "a reader was cut off: ", status.error_message());
    };
    return std::make_shared<ResultStore>(writer, &result_budget_, std::move(store_options));
  }

  grpc::ServerBidiReactor<v1::RunRequest, v1::JobEvent>* Run(
      grpc::CallbackServerContext* context) override {
    return new RunCall(this);
  }

  grpc::ServerUnaryReactor* GetStats(grpc::CallbackServerContext* context,
                                     const v1::GetStatsRequest* request,
                                     v1::Stats* stats) override {
    stats->set_queue_depth(static_cast<uint32_t>(queue_.size()));
    stats->set_queue_capacity(static_cast<uint32_t>(queue_.capacity()));
    stats->set_jobs_accepted(counters_.accepted);
    stats->set_jobs_succeeded(counters_.succeeded);
    stats->set_jobs_failed(counters_.failed);
    stats->set_jobs_cancelled(counters_.cancelled);
    stats->set_jobs_rejected(counters_.rejected);
    stats->set_job_running(counters_.job_running);
    stats->set_max_input_bytes(options_.max_input_bytes);
    stats->set_result_bytes_held(result_budget_.used());
    stats->set_result_bytes_limit(result_budget_.limit());
    stats->set_readers_cut_off(counters_.readers_cut_off);
    {
      std::lock_guard<std::mutex> lock(gl_mutex_);
      stats->set_gpu_available(!gl_renderer_.empty());
      stats->set_gl_renderer(gl_renderer_);
      stats->set_gl_device(gl_device_);
    }
    grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
    reactor->Finish(grpc::Status::OK);
    return reactor;
  }

  // Checks what can be checked before any input is read.
  absl::Status CheckSpec(const v1::JobSpec& spec) const {
    if (spec.input_kind() == v1::INPUT_KIND_UNSPECIFIED) {
      return absl::InvalidArgumentError("spec.input_kind is unspecified");
    }
    if (spec.input_bytes() == 0) return absl::InvalidArgumentError("spec.input_bytes is 0");
    if (spec.input_bytes() > options_.max_input_bytes) {
      return absl::ResourceExhaustedError(absl::StrCat("input of ", spec.input_bytes(),
                                                       " bytes is over this server's limit of ",
                                                       options_.max_input_bytes, " bytes"));
    }
    return absl::OkStatus();
  }

  std::string NextJobId() { return absl::StrFormat("job-%06d", next_job_number_.fetch_add(1) + 1); }

  const ServerOptions& options() const { return options_; }
  BoundedJobQueue<Job>& queue() { return queue_; }
  Counters& counters() { return counters_; }

  void SetGl(std::string renderer, std::string device) {
    std::lock_guard<std::mutex> lock(gl_mutex_);
    gl_renderer_ = std::move(renderer);
    gl_device_ = std::move(device);
  }

 private:
  const ServerOptions options_;
  BoundedJobQueue<Job> queue_;
  Counters counters_;
  MemoryBudget result_budget_;
  std::atomic<uint64_t> next_job_number_{0};
  std::mutex gl_mutex_;
  std::string gl_renderer_, gl_device_;
};

RunCall::RunCall(ServiceImpl* service)
    : service_(service), channel_(service->NewResultStore(&writer_)) {
  StartRead(&request_);
}

void RunCall::Fail(const absl::Status& status) {
  const grpc::Status grpc_status = ToGrpc(status);
  channel_->Finish(FailedEvent(grpc_status), grpc_status);
}

void RunCall::OnReadDone(bool ok) {
  if (!ok) {
    // The client closed its side (or the call broke) before the input was complete.
    if (!have_spec_) {
      Fail(absl::InvalidArgumentError("the call ended before a job spec was sent"));
    } else {
      Fail(absl::InvalidArgumentError(absl::StrCat("the input ended after ", input_.size(), " of ",
                                                   spec_.input_bytes(), " bytes")));
    }
    return;
  }
  if (!have_spec_) {
    if (!request_.has_spec()) {
      Fail(absl::InvalidArgumentError("the first message of a call must carry the job spec"));
      return;
    }
    if (absl::Status status = service_->CheckSpec(request_.spec()); !status.ok()) {
      if (status.code() == absl::StatusCode::kResourceExhausted) ++service_->counters().rejected;
      Fail(status);
      return;
    }
    spec_ = request_.spec();
    have_spec_ = true;
    input_.reserve(std::min<uint64_t>(spec_.input_bytes(), uint64_t{256} << 20));
  } else if (request_.has_spec()) {
    Fail(absl::InvalidArgumentError("a second job spec in the same call"));
    return;
  }
  const std::string& chunk = request_.chunk();
  if (input_.size() + chunk.size() > spec_.input_bytes()) {
    Fail(absl::InvalidArgumentError(
        absl::StrCat("more input than spec.input_bytes = ", spec_.input_bytes())));
    return;
  }
  input_.append(chunk);
  if (input_.size() == spec_.input_bytes()) {
    Submit();
    return;
  }
  StartRead(&request_);
}

void RunCall::Submit() {
  auto job = std::make_shared<Job>();
  job->id = service_->NextJobId();
  job->spec = std::move(spec_);
  job->input = std::move(input_);
  job->events = channel_;
  job->accepted_at = absl::Now();
  const std::string id = job->id;
  const uint64_t bytes = job->input.size();
  job_ = job;
  // The Accepted event is queued while the queue's lock is held, so it is always the
  // first event even if the worker picks the job up at once.
  absl::StatusOr<size_t> ahead = service_->queue().Push(std::move(job), [&](size_t jobs_ahead) {
    v1::JobEvent event;
    event.mutable_accepted()->set_job_id(id);
    event.mutable_accepted()->set_queue_position(static_cast<uint32_t>(jobs_ahead));
    event.mutable_accepted()->set_input_bytes(bytes);
    channel_->Emit(std::move(event));
    ++service_->counters().accepted;  // before a worker can finish it
  });
  if (!ahead.ok()) {
    ++service_->counters().rejected;
    LogLine(service_->options().log, id, " refused: ", ahead.status().message());
    Fail(ahead.status());
    return;
  }
  LogLine(service_->options().log, id, " accepted (", bytes, " bytes, ", *ahead, " ahead)");
}

void RunCall::OnCancel() {
  channel_->OnCancel();
  if (std::shared_ptr<Job> job = job_.lock()) {
    if (service_->queue().Remove(job.get())) {
      ++service_->counters().cancelled;
      LogLine(service_->options().log, job->id, " cancelled while queued");
    }
  }
}

}  // namespace

class ServerImpl {
 public:
  explicit ServerImpl(const ServerOptions& options) : service_(options) {}

  absl::Status Start() {
    const ServerOptions& options = service_.options();
    // The worker owns the GL context: it creates it on its own thread and reports back.
    std::promise<absl::Status> started;
    std::future<absl::Status> started_future = started.get_future();
    worker_ = std::thread([this, &started] { WorkerMain(started); });
    if (absl::Status status = started_future.get(); !status.ok()) {
      service_.queue().Stop();
      worker_.join();
      return status;
    }

    grpc::EnableDefaultHealthCheckService(true);
    grpc::reflection::InitProtoReflectionServerBuilderPlugin();
    grpc::ServerBuilder builder;
    if (!options.listen_address.empty()) {
      builder.AddListeningPort(options.listen_address, grpc::InsecureServerCredentials(), &port_);
    }
    builder.RegisterService(&service_);
    builder.SetMaxReceiveMessageSize(kMaxReceiveMessageBytes);
    builder.SetMaxSendMessageSize(-1);
    server_ = builder.BuildAndStart();
    if (server_ == nullptr || (!options.listen_address.empty() && port_ == 0)) {
      ShutdownWorker();
      return absl::UnavailableError(
          absl::StrCat("cannot listen on '", options.listen_address, "'"));
    }
    server_->GetHealthCheckService()->SetServingStatus(kServiceName, true);
    LogLine(
        options.log, "serving ", kServiceName,
        options.listen_address.empty() ? std::string(" in-process")
                                       : absl::StrCat(" on port ", port_),
        "; queue capacity ", options.queue_capacity, "; GL: ",
        gl_renderer_.empty() ? absl::StrCat("none (", gl_unavailable_reason_, ")") : gl_renderer_);
    return absl::OkStatus();
  }

  void Shutdown() {
    std::lock_guard<std::mutex> lock(shutdown_mutex_);
    if (shut_down_) return;
    shut_down_ = true;
    if (server_ != nullptr) {
      server_->GetHealthCheckService()->SetServingStatus(kServiceName, false);
      // Calls still open after the grace period are cancelled; their jobs see it.
      server_->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(2));
    }
    ShutdownWorker();
    if (server_ != nullptr) server_->Wait();
    shutdown_done_.notify_all();
  }

  void Wait() {
    std::unique_lock<std::mutex> lock(shutdown_mutex_);
    shutdown_done_.wait(lock, [&] { return shut_down_; });
  }

  int port() const { return port_; }
  std::shared_ptr<grpc::Channel> InProcessChannel() {
    grpc::ChannelArguments arguments;
    arguments.SetMaxReceiveMessageSize(-1);
    return server_->InProcessChannel(arguments);
  }
  std::string gl_renderer() const { return gl_renderer_; }
  std::string gl_unavailable_reason() const { return gl_unavailable_reason_; }

 private:
  void ShutdownWorker() {
    service_.queue().Stop();
    if (worker_.joinable()) worker_.join();
  }

  void WorkerMain(std::promise<absl::Status>& started) {
    const ServerOptions& options = service_.options();
    JobRunnerContext context;
#ifdef MLCLUST_HAVE_GPU
    std::unique_ptr<gpu::GlContext> gl;
    if (options.gpu != GpuMode::kOff) {
      absl::StatusOr<std::unique_ptr<gpu::GlContext>> created = gpu::GlContext::Create({});
      if (created.ok()) {
        gl = *std::move(created);
        context.gl = gl.get();
        gl_renderer_ = gl->renderer();
        context.gl_renderer = gl_renderer_;
        context.gl_is_software = gl->is_software();
        service_.SetGl(gl->renderer(), gl->device_description());
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

    Counters& counters = service_.counters();
    while (std::shared_ptr<Job> job = service_.queue().Pop()) {
      if (job->events->cancelled()) {
        ++counters.cancelled;
        continue;
      }
      counters.job_running = true;
      const absl::Time started_at = absl::Now();
      absl::StatusOr<JobOutcome> outcome = RunJob(*job, context);
      const absl::Time ended_at = absl::Now();
      if (outcome.ok()) {
        v1::JobEvent event;
        *event.mutable_done() = outcome->done;
        event.mutable_done()->set_seconds_queued(
            absl::ToDoubleSeconds(started_at - job->accepted_at));
        event.mutable_done()->set_seconds_running(absl::ToDoubleSeconds(ended_at - started_at));
        ++counters.succeeded;  // before Finish, so a client that saw Done sees it counted
        job->events->Finish(std::move(event), grpc::Status::OK);
        LogLine(options.log, job->id, " done in ", absl::FormatDuration(ended_at - started_at),
                ": ", outcome->done.levels(), " levels, ", outcome->done.triplets(), " triplets");
      } else {
        const grpc::Status status = ToGrpc(outcome.status());
        ++(outcome.status().code() == absl::StatusCode::kCancelled ? counters.cancelled
                                                                   : counters.failed);
        job->events->Finish(FailedEvent(status), status);
        LogLine(options.log, job->id, " failed: ", outcome.status().ToString());
      }
      counters.job_running = false;
    }
  }

  ServiceImpl service_;
  std::unique_ptr<grpc::Server> server_;
  std::thread worker_;
  int port_ = 0;
  std::string gl_renderer_, gl_unavailable_reason_;
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
std::shared_ptr<grpc::Channel> Server::InProcessChannel() { return impl_->InProcessChannel(); }
std::string Server::gl_renderer() const { return impl_->gl_renderer(); }
std::string Server::gl_unavailable_reason() const { return impl_->gl_unavailable_reason(); }
void Server::Wait() { impl_->Wait(); }
void Server::Shutdown() { impl_->Shutdown(); }

}  // namespace mlclust::server
