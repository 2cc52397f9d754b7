#include "client/replicas.h"

#include <arpa/inet.h>
#include <netdb.h>
#include <sys/socket.h>
#include <sys/types.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <random>
#include <thread>
#include <utility>

#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "absl/strings/strip.h"
#include "core/base/status_macros.h"
#include "grpcpp/grpcpp.h"
#include "mlclust/v1/mlclust.grpc.pb.h"

namespace mlclust::client {
namespace {

struct HostPort {
  std::string host;  // without brackets
  std::string port;
};

absl::StatusOr<HostPort> ParseHostPort(absl::string_view text, absl::string_view what) {
  HostPort out;
  size_t colon;
  if (absl::StartsWith(text, "[")) {
    const size_t close = text.find(']');
    if (close == absl::string_view::npos || close + 1 >= text.size() || text[close + 1] != ':') {
      return absl::InvalidArgumentError(absl::StrCat("--server: '", what, "' is not [IPv6]:PORT"));
    }
    out.host = std::string(text.substr(1, close - 1));
    colon = close + 1;
  } else {
    colon = text.rfind(':');
    if (colon == absl::string_view::npos || colon == 0) {
      return absl::InvalidArgumentError(
          absl::StrCat("--server: '", what, "' has no port: give HOST:PORT"));
    }
    out.host = std::string(text.substr(0, colon));
  }
  out.port = std::string(text.substr(colon + 1));
  uint32_t port = 0;
  if (!absl::SimpleAtoi(out.port, &port) || port < 1 || port > 65535) {
    return absl::InvalidArgumentError(
        absl::StrCat("--server: '", what, "' has no port in 1-65535: give HOST:PORT"));
  }
  return out;
}

// Every address of `host` (getaddrinfo), as HOST:PORT.
absl::StatusOr<std::vector<std::string>> Resolve(const HostPort& target, const std::string& uri) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  const int error = getaddrinfo(target.host.c_str(), target.port.c_str(), &hints, &found);
  if (error != 0) {
    return absl::NotFoundError(
        absl::StrCat("--server: cannot resolve ", uri, " (", gai_strerror(error), ")"));
  }
  std::vector<std::string> out;
  for (const addrinfo* a = found; a != nullptr; a = a->ai_next) {
    char text[INET6_ADDRSTRLEN] = {};
    if (a->ai_family == AF_INET) {
      const auto* in = reinterpret_cast<const sockaddr_in*>(a->ai_addr);
      inet_ntop(AF_INET, &in->sin_addr, text, sizeof(text));
      out.push_back(absl::StrCat(text, ":", target.port));
    } else if (a->ai_family == AF_INET6) {
      const auto* in = reinterpret_cast<const sockaddr_in6*>(a->ai_addr);
      inet_ntop(AF_INET6, &in->sin6_addr, text, sizeof(text));
      out.push_back(absl::StrCat("[", text, "]:", target.port));
    }
  }
  freeaddrinfo(found);
  if (out.empty()) {
    return absl::NotFoundError(absl::StrCat("--server: ", uri, " resolves to no address"));
  }
  return out;
}

// Load of a replica as GetStats tells it, or nullopt when it does not answer or drains.
std::optional<uint64_t> ProbeLoad(const std::string& replica, const ReplicaOptions& options) {
  absl::StatusOr<std::shared_ptr<grpc::Channel>> channel = Connect(replica, options.connect);
  if (!channel.ok()) return std::nullopt;
  auto stub = v1::Clustering::NewStub(*channel);
  grpc::ClientContext context;
  context.set_deadline(absl::ToChronoTime(absl::Now() + options.probe_deadline));
  v1::Stats stats;
  if (!stub->GetStats(&context, v1::GetStatsRequest(), &stats).ok() || stats.draining()) {
    return std::nullopt;
  }
  return uint64_t{stats.queue_depth()} + stats.jobs_running() + (stats.job_running() ? 1 : 0);
}

// What is left of `deadline` (one for all the replicas tried) since `start`.
absl::StatusOr<absl::Duration> DeadlineLeft(absl::Duration deadline, absl::Time start) {
  if (deadline == absl::InfiniteDuration()) return deadline;
  const absl::Duration left = deadline - (absl::Now() - start);
  if (left <= absl::ZeroDuration()) {
    return absl::DeadlineExceededError("the deadline passed while trying replicas");
  }
  return left;
}

// A replica that accepted a job was lost (it died, was drained with the job, or the stream
// broke before the job's final event), rather than the job failing or being cancelled on
// it, or the caller's own deadline.
bool LostReplica(const absl::Status& status, bool saw_final) {
  return status.code() == absl::StatusCode::kUnavailable || (IsBrokenStream(status) && !saw_final);
}

// Tries `attempt` on each replica in turn until one accepts the job (`accepted` set by the
// attempt once the Accepted event arrived, `saw_final` once the job's final event did). A
// replica lost after accepting the job: the job is submitted again (the replicas in a
// fresh order, the lost one last), at most options.max_resubmits times, `levels_kept`
// telling on_resubmit how many levels are kept.
template <typename T>
absl::StatusOr<T> OnReplicas(
    const std::vector<std::string>& replicas, const ReplicaOptions& options, std::string* replica,
    const std::function<size_t()>& levels_kept,
    const std::function<absl::StatusOr<T>(const std::shared_ptr<grpc::Channel>&, bool* accepted,
                                          bool* saw_final)>& attempt) {
  if (replicas.empty()) return absl::InvalidArgumentError("--server names no replica");
  std::vector<std::string> order = OrderReplicas(replicas, options);
  std::vector<std::string> refused;
  std::vector<std::string> lost;  // "ADDRESS (why)", one per resubmission
  for (size_t next = 0;;) {
    if (next == order.size()) {
      if (lost.empty()) {
        return absl::UnavailableError(
            absl::StrCat("no replica accepted the job: ", absl::StrJoin(refused, "; ")));
      }
      return absl::UnavailableError(
          absl::StrCat("the job was lost with replica ", absl::StrJoin(lost, ", then "),
                       ", and no replica accepted it again: ", absl::StrJoin(refused, "; ")));
    }
    const std::string address = order[next++];
    if (replica != nullptr) *replica = address;
    absl::StatusOr<std::shared_ptr<grpc::Channel>> channel = Connect(address, options.connect);
    if (!channel.ok()) return channel.status();
    bool accepted = false;
    bool saw_final = false;
    absl::StatusOr<T> result = attempt(*channel, &accepted, &saw_final);
    if (result.ok()) return result;
    const absl::Status& status = result.status();
    if (accepted) {
      if (!LostReplica(status, saw_final)) {
        // Failed or cancelled on its replica, or the caller's deadline: the job's own end.
        return absl::Status(status.code(),
                            absl::StrCat("replica ", address, ": ", status.message()));
      }
      lost.push_back(absl::StrCat(address, " (", status.message(), ")"));
      if (static_cast<int>(lost.size()) > options.max_resubmits) {
        return absl::UnavailableError(absl::StrCat(
            "replica ", address,
            " accepted the job and then became unreachable (gRPC: ", status.message(),
            "); the job was submitted again ", lost.size() - 1, " times, the limit (--resubmit ",
            options.max_resubmits, "): lost with replica ", absl::StrJoin(lost, ", then ")));
      }
      if (options.on_resubmit) {
        options.on_resubmit(Resubmission{address, status, static_cast<int>(lost.size()),
                                         options.max_resubmits, levels_kept()});
      }
      // The next healthy replica: a fresh order (the lost one answers no GetStats), the lost
      // one last, for it may have been restarted at its address.
      order = OrderReplicas(replicas, options);
      std::stable_partition(order.begin(), order.end(),
                            [&](const std::string& r) { return r != address; });
      refused.clear();
      next = 0;
      continue;
    }
    if (!TryAnotherReplica(status)) {
      return absl::Status(status.code(), absl::StrCat("replica ", address, ": ", status.message()));
    }
    refused.push_back(absl::StrCat(address, " (", status.message(), ")"));
    if (options.on_retry) options.on_retry(address, status);
  }
}

}  // namespace

bool NamesReplicas(const std::string& servers) {
  return absl::StrContains(servers, ',') || absl::StartsWith(servers, "dns:");
}

absl::StatusOr<std::vector<std::string>> ResolveReplicas(const std::string& servers) {
  std::vector<std::string> out;
  auto add = [&](std::string address) {
    if (std::find(out.begin(), out.end(), address) == out.end()) out.push_back(std::move(address));
  };
  for (absl::string_view item : absl::StrSplit(servers, ',')) {
    item = absl::StripAsciiWhitespace(item);
    if (item.empty()) {
      return absl::InvalidArgumentError(
          absl::StrCat("--server: '", servers, "' has an empty item: give A:PORT,B:PORT,..."));
    }
    if (absl::ConsumePrefix(&item, "dns:")) {
      const std::string uri = absl::StrCat("dns:", item);
      if (absl::ConsumePrefix(&item, "//")) {
        // dns://AUTHORITY/NAME:PORT: the authority (a DNS server) is left to the system's.
        const size_t slash = item.find('/');
        if (slash == absl::string_view::npos) {
          return absl::InvalidArgumentError(
              absl::StrCat("--server: '", uri, "' is not dns:///NAME:PORT"));
        }
        item.remove_prefix(slash + 1);
      }
      absl::StatusOr<HostPort> target = ParseHostPort(item, uri);
      if (!target.ok()) return target.status();
      absl::StatusOr<std::vector<std::string>> addresses = Resolve(*target, uri);
      if (!addresses.ok()) return addresses.status();
      for (std::string& address : *addresses) add(std::move(address));
      continue;
    }
    absl::StatusOr<HostPort> target = ParseHostPort(item, item);
    if (!target.ok()) return target.status();
    add(std::string(item));
  }
  return out;
}

std::string ReplicaJobId(const std::string& replica, const std::string& job_id) {
  return absl::StrCat(replica, "/", job_id);
}

std::optional<SplitJobId> SplitReplicaJobId(const std::string& id) {
  const size_t slash = id.rfind('/');
  if (slash == std::string::npos || slash == 0 || slash + 1 >= id.size()) return std::nullopt;
  SplitJobId out{id.substr(0, slash), id.substr(slash + 1)};
  if (!ParseHostPort(out.replica, out.replica).ok()) return std::nullopt;
  return out;
}

std::vector<std::string> OrderReplicas(const std::vector<std::string>& replicas,
                                       const ReplicaOptions& options) {
  if (options.in_order) return replicas;
  std::vector<std::optional<uint64_t>> load(replicas.size());
  {
    std::vector<std::thread> probes;
    probes.reserve(replicas.size());
    for (size_t i = 0; i < replicas.size(); ++i) {
      probes.emplace_back([&, i] { load[i] = ProbeLoad(replicas[i], options); });
    }
    for (std::thread& probe : probes) probe.join();
  }
  std::vector<size_t> order(replicas.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::mt19937_64 random(std::random_device{}() ^ static_cast<uint64_t>(getpid()));
  std::shuffle(order.begin(), order.end(), random);
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    const uint64_t none = UINT64_MAX;
    return load[a].value_or(none) < load[b].value_or(none);
  });
  std::vector<std::string> out;
  out.reserve(order.size());
  for (size_t i : order) out.push_back(replicas[i]);
  return out;
}

bool TryAnotherReplica(const absl::Status& status) {
  return status.code() == absl::StatusCode::kUnavailable ||
         status.code() == absl::StatusCode::kResourceExhausted;
}

absl::StatusOr<JobResult> RunJobOnReplicas(const std::vector<std::string>& replicas,
                                           const v1::JobSpec& spec, std::string_view input,
                                           const RunOptions& run_options,
                                           const ReplicaOptions& options, std::string* replica) {
  const absl::Time start = absl::Now();
  // The levels received, kept across the replicas the job is submitted to.
  ReceivedLevels own;
  ReceivedLevels& received = run_options.received != nullptr ? *run_options.received : own;
  return OnReplicas<JobResult>(
      replicas, options, replica, [&] { return received.levels(); },
      [&](const std::shared_ptr<grpc::Channel>& channel, bool* accepted,
          bool* saw_final) -> absl::StatusOr<JobResult> {
        RunOptions attempt = run_options;
        MLCLUST_ASSIGN_OR_RETURN(attempt.deadline, DeadlineLeft(run_options.deadline, start));
        attempt.received = &received;
        attempt.on_event = [&](const v1::JobEvent& event) {
          if (event.has_accepted()) *accepted = true;
          if (run_options.on_event) run_options.on_event(event);
        };
        absl::StatusOr<JobResult> result = RunJob(channel, spec, input, attempt);
        *saw_final = received.saw_final();
        return result;
      });
}

absl::StatusOr<v1::Accepted> SubmitDetachedOnReplicas(
    const std::vector<std::string>& replicas, const v1::JobSpec& spec, std::string_view input,
    const RunOptions& run_options, const ReplicaOptions& options, std::string* replica) {
  std::string used;
  const absl::Time start = absl::Now();
  absl::StatusOr<v1::Accepted> accepted = OnReplicas<v1::Accepted>(
      replicas, options, &used, [] { return size_t{0}; },
      [&](const std::shared_ptr<grpc::Channel>& channel, bool* seen,
          bool* saw_final) -> absl::StatusOr<v1::Accepted> {
        RunOptions attempt = run_options;
        MLCLUST_ASSIGN_OR_RETURN(attempt.deadline, DeadlineLeft(run_options.deadline, start));
        attempt.on_event = [&](const v1::JobEvent& event) {
          if (event.has_accepted()) *seen = true;
          *saw_final = *saw_final || event.final();
          if (run_options.on_event) run_options.on_event(event);
        };
        return SubmitDetached(channel, spec, input, attempt);
      });
  if (replica != nullptr) *replica = used;
  if (!accepted.ok()) return accepted.status();
  accepted->set_job_id(ReplicaJobId(used, accepted->job_id()));
  return accepted;
}

absl::StatusOr<JobResult> WatchOnReplicas(const std::vector<std::string>& replicas,
                                          const std::string& job_id, const v1::JobSpec& spec,
                                          std::string_view input, const WatchOptions& watch,
                                          const ReplicaOptions& options,
                                          std::string* final_job_id) {
  std::optional<SplitJobId> split = SplitReplicaJobId(job_id);
  if (!split.has_value()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "job id '", job_id, "' does not name its replica: give the id HOST:PORT/JOBID"));
  }
  const absl::Time start = absl::Now();
  ReceivedLevels own;
  ReceivedLevels& received = watch.received != nullptr ? *watch.received : own;
  std::string current = job_id;
  int resubmits = 0;
  while (true) {
    if (final_job_id != nullptr) *final_job_id = current;
    absl::StatusOr<std::shared_ptr<grpc::Channel>> channel =
        Connect(split->replica, options.connect);
    if (!channel.ok()) return channel.status();
    WatchOptions attempt = watch;
    MLCLUST_ASSIGN_OR_RETURN(attempt.deadline, DeadlineLeft(watch.deadline, start));
    attempt.received = &received;
    absl::StatusOr<JobResult> result = WatchJob(*channel, split->job_id, attempt);
    if (result.ok()) {
      result->job_id = current;
      return result;
    }
    if (!LostReplica(result.status(), received.saw_final())) {
      return ExplainReplicaFailure(result.status(), split->replica, split->job_id);
    }
    if (resubmits == options.max_resubmits) {
      return absl::UnavailableError(absl::StrCat(
          "replica ", split->replica, ", which holds job ", split->job_id,
          ", does not answer (gRPC: ", result.status().message(), "); the job was submitted again ",
          resubmits, " times, the limit (--resubmit ", options.max_resubmits, ")"));
    }
    ++resubmits;
    if (options.on_resubmit) {
      options.on_resubmit(Resubmission{split->replica, result.status(), resubmits,
                                       options.max_resubmits, received.levels()});
    }
    // The next healthy replica: OrderReplicas' order, the lost one last (it may have been
    // restarted at its address).
    std::vector<std::string> others = OrderReplicas(replicas, options);
    std::stable_partition(others.begin(), others.end(),
                          [&](const std::string& r) { return r != split->replica; });
    ReplicaOptions submit = options;
    submit.in_order = true;
    submit.max_resubmits = 0;
    RunOptions upload;
    MLCLUST_ASSIGN_OR_RETURN(upload.deadline, DeadlineLeft(watch.deadline, start));
    MLCLUST_ASSIGN_OR_RETURN(
        const v1::Accepted accepted,
        SubmitDetachedOnReplicas(others, spec, input, upload, submit, nullptr));
    current = accepted.job_id();
    split = SplitReplicaJobId(current);
  }
}

absl::Status ExplainReplicaFailure(const absl::Status& status, const std::string& replica,
                                   const std::string& job_id) {
  if (status.ok()) return status;
  if (status.code() == absl::StatusCode::kUnavailable) {
    return absl::UnavailableError(absl::StrCat(
        "replica ", replica, ", which holds job ", job_id,
        ", does not answer: it was stopped or died, and its jobs and their results went with "
        "it (replicas share nothing). Submit the job again, from its input and options: its "
        "levels are the same (WatchOnReplicas does it for a client that kept them) (gRPC: ",
        status.message(), ")"));
  }
  return absl::Status(status.code(), absl::StrCat("replica ", replica, ": ", status.message()));
}

}  // namespace mlclust::client
