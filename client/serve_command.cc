#include "client/serve_command.h"

#include <pthread.h>

#include <csignal>
#include <cstdio>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "absl/time/time.h"
#include "server/auth.h"
#include "server/memory_limit.h"
#include "server/server.h"

namespace mlclust::cli {
namespace {

absl::StatusOr<std::string> ReadFlagFile(const Arguments& flags, const std::string& name) {
  if (!flags.has(name)) return std::string();
  const std::string path = flags.get(name);
  std::ifstream in(path, std::ios::binary);
  if (!in) return absl::InvalidArgumentError(absl::StrCat("--", name, ": cannot read ", path));
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

int RunServe(const Arguments& flags) {
  if (!flags.positional().empty()) {
    return Fail(absl::InvalidArgumentError(
        absl::StrCat("serve: unexpected argument '", flags.positional()[0], "'")));
  }
  server::ServerOptions options;
  options.listen_address = flags.get("listen", "127.0.0.1:50051");
  // Each numeric flag: its name, where it goes, the unit it is given in (bytes per unit).
  struct Number {
    const char* name;
    uint64_t* bytes;
    uint32_t* count;
    size_t* size;
    uint64_t unit;
  };
  uint64_t drain_seconds = 30;
  uint64_t retention_seconds = 3600;
  uint64_t upload_idle_seconds = 30;
  uint64_t watch_idle_seconds = 60;
  uint64_t upload_min_kib = options.upload_min_bytes_per_second >> 10;
  const Number numbers[] = {
      {"queue", nullptr, nullptr, &options.queue_capacity, 1},
      {"workers", nullptr, nullptr, &options.cpu_workers, 1},
      {"max-input-mb", &options.max_input_bytes, nullptr, nullptr, 1 << 20},
      {"max-queued-mb", &options.max_queued_input_bytes, nullptr, nullptr, 1 << 20},
      {"max-upload-mb", &options.max_upload_bytes_in_flight, nullptr, nullptr, 1 << 20},
      {"result-job-mb", &options.result_job_budget_bytes, nullptr, nullptr, 1 << 20},
      {"result-total-mb", &options.result_server_budget_bytes, nullptr, nullptr, 1 << 20},
      {"max-calls", nullptr, &options.max_calls, nullptr, 1},
      {"max-calls-per-connection", nullptr, &options.max_calls_per_connection, nullptr, 1},
      {"max-calls-per-peer", nullptr, &options.max_calls_per_peer, nullptr, 1},
      {"max-calls-per-tenant", nullptr, &options.max_calls_per_tenant, nullptr, 1},
      {"upload-idle-seconds", &upload_idle_seconds, nullptr, nullptr, 1},
      {"upload-min-kib-per-second", &upload_min_kib, nullptr, nullptr, 1},
      {"watch-idle-seconds", &watch_idle_seconds, nullptr, nullptr, 1},
      {"drain-seconds", &drain_seconds, nullptr, nullptr, 1},
      {"retention-seconds", &retention_seconds, nullptr, nullptr, 1},
      {"kept-results-mb", &options.kept_results_bytes, nullptr, nullptr, 1 << 20},
      {"max-jobs-per-tenant", nullptr, &options.max_jobs_per_tenant, nullptr, 1},
  };
  for (const Number& number : numbers) {
    const uint64_t current = number.bytes   ? *number.bytes / number.unit
                             : number.count ? *number.count
                                            : *number.size;
    absl::StatusOr<uint64_t> value = flags.GetUint(number.name, current);
    if (!value.ok()) return Fail(value.status());
    const uint64_t limit = number.count != nullptr ? 0xffffffffu : (uint64_t{1} << 44);
    if (*value > limit) {
      return Fail(absl::InvalidArgumentError(
          absl::StrCat("--", number.name, ": ", *value, " is over ", limit)));
    }
    if (number.bytes != nullptr) *number.bytes = *value * number.unit;
    if (number.count != nullptr) *number.count = static_cast<uint32_t>(*value);
    if (number.size != nullptr) *number.size = static_cast<size_t>(*value);
  }
  if (options.cpu_workers > 256) return Fail(absl::InvalidArgumentError("--workers: over 256"));
  if (options.queue_capacity > 100000) {
    return Fail(absl::InvalidArgumentError("--queue: over 100000"));
  }
  if (upload_idle_seconds < 1 || upload_idle_seconds > 3600) {
    return Fail(absl::InvalidArgumentError(
        absl::StrCat("--upload-idle-seconds must be 1 to 3600, not ", upload_idle_seconds)));
  }
  if (upload_min_kib > (1 << 20)) {
    return Fail(absl::InvalidArgumentError(absl::StrCat(
        "--upload-min-kib-per-second must be at most 1048576 (1 GiB/s), not ", upload_min_kib)));
  }
  if (watch_idle_seconds < 1 || watch_idle_seconds > 3600) {
    return Fail(absl::InvalidArgumentError(
        absl::StrCat("--watch-idle-seconds must be 1 to 3600, not ", watch_idle_seconds)));
  }
  options.watch_idle_timeout = absl::Seconds(static_cast<double>(watch_idle_seconds));
  options.upload_idle_timeout = absl::Seconds(static_cast<double>(upload_idle_seconds));
  options.upload_min_bytes_per_second = upload_min_kib << 10;
  options.drain_time = absl::Seconds(static_cast<double>(drain_seconds));
  options.result_retention = absl::Seconds(static_cast<double>(retention_seconds));
  options.metrics_address = flags.get("metrics", options.metrics_address);
  options.list_all_jobs = flags.has("list-all-jobs");
  options.metrics_allow_remote = flags.has("metrics-allow-remote");
  if (flags.has("log-format")) {
    const std::string format = flags.get("log-format");
    if (format != "text" && format != "json") {
      return Fail(absl::InvalidArgumentError("--log-format must be text or json"));
    }
    options.log_json = format == "json";
  }
  for (auto [name, pem] :
       {std::pair{"tls-cert", &options.tls_cert_pem}, std::pair{"tls-key", &options.tls_key_pem},
        std::pair{"tls-client-ca", &options.tls_client_ca_pem}}) {
    absl::StatusOr<std::string> text = ReadFlagFile(flags, name);
    if (!text.ok()) return Fail(text.status());
    *pem = *std::move(text);
  }
  if (flags.has("auth-token-file")) {
    absl::StatusOr<std::string> text = ReadFlagFile(flags, "auth-token-file");
    if (!text.ok()) return Fail(text.status());
    absl::StatusOr<std::map<std::string, std::string>> tokens = server::ParseTokenFile(*text);
    if (!tokens.ok()) {
      return Fail(absl::InvalidArgumentError(absl::StrCat(
          "--auth-token-file ", flags.get("auth-token-file"), ": ", tokens.status().message())));
    }
    options.auth_tokens = *std::move(tokens);
  }
  // The memory the budgets may take, against what the server is given (issue 24 item 8).
  const server::MemoryNeeded needed = server::MemoryNeededFor(options);
  if (flags.has("memory-needed")) {
    std::printf("%llu\n", static_cast<unsigned long long>(needed.total() >> 20));
    return 0;
  }
  std::optional<uint64_t> memory_limit = server::CgroupMemoryLimit();
  if (flags.has("memory-limit-mb")) {
    absl::StatusOr<uint64_t> mb = flags.GetUint("memory-limit-mb", 0);
    if (!mb.ok()) return Fail(mb.status());
    memory_limit = *mb << 20;
  }
  if (absl::Status fits = server::CheckMemoryFits(needed, memory_limit); !fits.ok()) {
    return Fail(fits);
  }
  if (!server::RunningJobsFit(needed, memory_limit)) {
    std::fprintf(stderr,
                 "mlclust: warning: with (1 + --workers) jobs of --max-input-mb running, the "
                 "server may need %llu MiB, over its memory limit of %llu MiB\n",
                 static_cast<unsigned long long>(needed.total() >> 20),
                 static_cast<unsigned long long>(*memory_limit >> 20));
  }
  const std::string gpu = flags.get("gpu", "auto");
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
  if (!options.log_json) {
    std::fprintf(stderr, "mlclust: listening on port %d (Ctrl-C to stop)\n", (*server)->port());
  }
  int received = 0;
  sigwait(&signals, &received);
  if (!options.log_json) {
    std::fprintf(stderr, "mlclust: signal %d, draining (up to %llu s for running jobs)\n", received,
                 static_cast<unsigned long long>(drain_seconds));
  }
  (*server)->Shutdown();
  if (!options.log_json) {
    std::fprintf(stderr, "mlclust: stopped\n");
  }
  return 0;
}

}  // namespace

Command ServeCommand() {
  return {
      {"serve",
       "[--listen ADDR] [--workers N] [--queue N] [--max-input-mb N]\n"
       "                [--max-queued-mb N] [--gpu auto|on|off] [--drain-seconds S] [limits]",
       "Runs the gRPC server until SIGINT or SIGTERM (then drains: health NOT_SERVING and new "
       "jobs refused at once, queued jobs end with UNAVAILABLE, running ones may finish within "
       "--drain-seconds, default 30, then are cancelled).",
       {{"",
         {{"listen", "ADDR",
           "default 127.0.0.1:50051 (loopback). Any other address is plaintext without "
           "authentication: a warning is printed. A port already in use is refused."},
          {"workers", "N",
           "CPU workers beside the worker that owns the GL context (default 0: that one worker "
           "runs every job in order)"},
          {"queue", "N", "jobs that may wait (default 16); more are refused at once"},
          {"max-input-mb", "N", "largest input of one job (default 1024)"},
          {"max-queued-mb", "N", "the inputs of all waiting jobs together (default 4096)"},
          {"gpu", "auto|on|off", "the GL context: where there is one (default), required, or none"},
          {"drain-seconds", "S", "how long running jobs may finish after SIGTERM (default 30)"}}},
        {"limits (each refusal is RESOURCE_EXHAUSTED with a message, logged and counted):",
         {{"max-upload-mb", "N", "bytes of uploads in progress, all calls together (default 1024)"},
          {"max-calls", "N", "calls in progress (default 256)"},
          {"max-calls-per-connection", "N", "calls in progress on one connection (default 32)"},
          {"max-calls-per-peer", "N",
           "calls in progress per client address (default 64; behind a proxy every client "
           "has the proxy's address: raise it toward --max-calls)"},
          {"max-calls-per-tenant", "N",
           "with tokens, calls in progress per tenant (default 64; 0: no limit)"},
          {"upload-idle-seconds", "S",
           "a job's upload that receives nothing for S seconds is ended with "
           "DEADLINE_EXCEEDED (default 30; 1 to 3600), so stalled calls give their slots back"},
          {"upload-min-kib-per-second", "N",
           "an upload slower than N KiB/s on average (after its first --upload-idle-seconds) "
           "is ended with DEADLINE_EXCEEDED (default 64; 0: no minimum)"},
          {"result-job-mb", "N",
           "events a job's client may leave unread (memory; default 256) before it is cut off "
           "with RESOURCE_EXHAUSTED (producing levels never waits on a reader); the job runs on "
           "and keeps its levels, and the message says to `watch` it"},
          {"result-total-mb", "N",
           "the same over all jobs, and the events watchers are being sent (default 1024)"},
          {"watch-idle-seconds", "S",
           "a watch whose client takes no event for S seconds is cut off (default 60; 1 to "
           "3600); watch calls are admitted like jobs (--max-calls and the limits per "
           "connection, address and tenant)"}}},
        {"kept results (every job's levels, for watch; cancel, jobs):",
         {{"retention-seconds", "S", "an ended job's results are kept this long (default 3600)"},
          {"kept-results-mb", "N",
           "memory for kept levels, all jobs together (default 1024); the oldest ended jobs' "
           "results are dropped first to make room"},
          {"max-jobs-per-tenant", "N",
           "jobs one tenant may have queued or running (default 0: no limit; without tokens "
           "every client is one tenant)"}}},
        {"security (plaintext is meant for loopback only):",
         {{"tls-cert", "FILE", "TLS with this certificate chain (PEM; with --tls-key)"},
          {"tls-key", "FILE", "the key of --tls-cert (PEM)"},
          {"tls-client-ca", "FILE", "require client certificates signed by this CA (PEM)"},
          {"auth-token-file", "F",
           "bearer tokens, one \"TOKEN TENANT\" per line (needs TLS): every call needs a known "
           "token (UNAUTHENTICATED otherwise) and sees only its tenant's jobs (another tenant's "
           "job answers NOT_FOUND exactly like an unknown id); health checks need none, server "
           "reflection needs one like every other service. Tokens are never logged."},
          {"list-all-jobs", "",
           "without tokens, `jobs` lists every job (a single-user server); by default it lists "
           "only the jobs submitted on the caller's own connection (none over unix sockets). "
           "Job ids are 128 random bits: watch and cancel work for whoever was given one."}}},
        {"operations:",
         {{"metrics", "ADDR",
           "Prometheus metrics over HTTP at ADDR/metrics (HOST:PORT): jobs by state and "
           "algorithm, queue depth, job durations (histograms), bytes in and out, the device. "
           "Plain HTTP without a token: with --auth-token-file it must be a loopback address "
           "(scrape through a sidecar or a port forward) unless --metrics-allow-remote"},
          {"metrics-allow-remote", "",
           "serve --metrics on a non-loopback address although tokens are on (a private "
           "network)"},
          {"memory-needed", "",
           "print the most memory (MiB) these flags let the server use (running jobs, queued "
           "inputs, uploads, unread events, kept results, the process) and exit: the figure for "
           "a container's memory request and limit. The server refuses to start where its "
           "cgroup's memory limit is below its budgets, and warns where below this figure"},
          {"memory-limit-mb", "N", "check the budgets against N MiB instead of the cgroup's limit"},
          {"log-format", "text|json",
           "json: one JSON object per line (job id, tenant, algorithm, sizes, durations, "
           "outcome)"}}}}},
      RunServe};
}

}  // namespace mlclust::cli
