#include "client/serve_command.h"

#include <pthread.h>

#include <csignal>
#include <cstdio>
#include <map>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "server/server.h"

namespace mlclust::cli {
namespace {

constexpr char kServeUsage[] =
    R"(  mlclust serve [--listen ADDR] [--queue N] [--max-input-mb N] [--gpu auto|on|off]
                [--result-job-mb N] [--result-total-mb N]
      Runs the gRPC server (default ADDR 0.0.0.0:50051) until interrupted.
      --result-job-mb N    events a job's client may leave unread (memory; default 256)
                           before it is cut off with RESOURCE_EXHAUSTED and the job
                           cancelled: producing levels never waits on a reader
      --result-total-mb N  the same over all jobs (default 1024)
)";

// --name value / --name=value; every name must be one `serve` knows.
absl::StatusOr<std::map<std::string, std::string>> ParseFlags(int argc, char** argv) {
  static const char* const kKnown[] = {"listen", "queue",         "max-input-mb",
                                       "gpu",    "result-job-mb", "result-total-mb"};
  std::map<std::string, std::string> flags;
  for (int i = 0; i < argc; ++i) {
    const std::string arg = argv[i];
    if (!absl::StartsWith(arg, "--")) {
      return absl::InvalidArgumentError(absl::StrCat("serve: unexpected argument '", arg, "'"));
    }
    std::string name = arg.substr(2), value;
    if (const size_t eq = name.find('='); eq != std::string::npos) {
      value = name.substr(eq + 1);
      name = name.substr(0, eq);
    } else {
      if (i + 1 >= argc) return absl::InvalidArgumentError(absl::StrCat(arg, " needs a value"));
      value = argv[++i];
    }
    bool known = false;
    for (const char* k : kKnown) known = known || name == k;
    if (!known) return absl::InvalidArgumentError(absl::StrCat("unknown option --", name));
    flags[name] = value;
  }
  return flags;
}

absl::StatusOr<uint64_t> GetUint(const std::map<std::string, std::string>& flags,
                                 const std::string& name, uint64_t fallback) {
  auto it = flags.find(name);
  if (it == flags.end()) return fallback;
  uint64_t value;
  if (!absl::SimpleAtoi(it->second, &value)) {
    return absl::InvalidArgumentError(
        absl::StrCat("--", name, ": '", it->second, "' is not a non-negative integer"));
  }
  return value;
}

int Fail(const absl::Status& status) {
  std::fprintf(stderr, "mlclust: %s\n", std::string(status.message()).c_str());
  return status.code() == absl::StatusCode::kInvalidArgument ? 2 : 1;
}

}  // namespace

const char* ServeUsage() { return kServeUsage; }

int RunServeCommand(int argc, char** argv) {
  if (argc == 1 && (std::string(argv[0]) == "--help" || std::string(argv[0]) == "help")) {
    std::fputs(kServeUsage, stdout);
    return 0;
  }
  absl::StatusOr<std::map<std::string, std::string>> flags = ParseFlags(argc, argv);
  if (!flags.ok()) return Fail(flags.status());
  server::ServerOptions options;
  auto listen = flags->find("listen");
  options.listen_address = listen == flags->end() ? "0.0.0.0:50051" : listen->second;
  absl::StatusOr<uint64_t> queue = GetUint(*flags, "queue", options.queue_capacity);
  absl::StatusOr<uint64_t> max_mb = GetUint(*flags, "max-input-mb", options.max_input_bytes >> 20);
  if (!queue.ok()) return Fail(queue.status());
  if (!max_mb.ok()) return Fail(max_mb.status());
  options.queue_capacity = *queue;
  options.max_input_bytes = *max_mb << 20;
  absl::StatusOr<uint64_t> result_job_mb =
      GetUint(*flags, "result-job-mb", options.result_job_budget_bytes >> 20);
  absl::StatusOr<uint64_t> result_total_mb =
      GetUint(*flags, "result-total-mb", options.result_server_budget_bytes >> 20);
  if (!result_job_mb.ok()) return Fail(result_job_mb.status());
  if (!result_total_mb.ok()) return Fail(result_total_mb.status());
  options.result_job_budget_bytes = *result_job_mb << 20;
  options.result_server_budget_bytes = *result_total_mb << 20;
  auto gpu_flag = flags->find("gpu");
  const std::string gpu = gpu_flag == flags->end() ? "auto" : gpu_flag->second;
  if (gpu == "auto")
    options.gpu = server::GpuMode::kAuto;
  else if (gpu == "on")
    options.gpu = server::GpuMode::kOn;
  else if (gpu == "off")
    options.gpu = server::GpuMode::kOff;
  else
    return Fail(absl::InvalidArgumentError("--gpu must be auto, on or off"));

  // Shut down cleanly on SIGINT / SIGTERM: this thread waits for the signal synchronously.
  // The signals are blocked before the server starts its threads, which inherit the mask,
  // so none of them can take the signal's default action.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  absl::StatusOr<std::unique_ptr<server::Server>> server = server::Server::Start(options);
  if (!server.ok()) return Fail(server.status());
  std::fprintf(stderr, "mlclust: listening on port %d (Ctrl-C to stop)\n", (*server)->port());
  int received = 0;
  sigwait(&signals, &received);
  std::fprintf(stderr, "mlclust: signal %d, shutting down\n", received);
  (*server)->Shutdown();
  return 0;
}

}  // namespace mlclust::cli
