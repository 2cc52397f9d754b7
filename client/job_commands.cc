#include "client/job_commands.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "client/clustered_mesh_file.h"
#include "client/job_cli.h"
#include "client/progress_bar.h"
#include "client/replicas.h"
#include "core/cluster/registry.h"
#include "core/io/mesh_io.h"

namespace mlclust::cli {
namespace {

// --quiet of cancel and jobs: accepted as by every command that talks to a server.
const Flag kNoProgressRow("quiet", "", "accepted as by watch; these print no progress line", 'q');

constexpr char kJobServerHelp[] =
    "the server that accepted the job (not needed for an id HOST:PORT/JOBID)";

absl::StatusOr<ServerFlags> RequireServer(const Arguments& flags, const std::string& command) {
  absl::StatusOr<ServerFlags> server = ServerFlagsFrom(flags);
  if (!server.ok()) return server.status();
  if (server->server.empty()) {
    return absl::InvalidArgumentError(
        absl::StrCat(command,
                     ": give --server ADDR (the server that accepted the job; an embedded server "
                     "ends with the command that started it)"));
  }
  return server;
}

absl::StatusOr<std::string> OneJobId(const Arguments& flags, const std::string& command) {
  if (flags.positional().size() != 1) {
    return absl::InvalidArgumentError(absl::StrCat(command, ": give exactly one JOB id"));
  }
  return flags.positional()[0];
}

// A job id "HOST:PORT/JOBID" (a job submitted to several replicas) goes to its replica,
// whatever --server says (it may be left out); others to --server.
struct RoutedJob {
  ServerFlags server;
  std::string job_id;   // the server's id
  std::string replica;  // empty: the id named none
};
absl::StatusOr<RoutedJob> RouteJob(const Arguments& flags, const std::string& command) {
  absl::StatusOr<std::string> id = OneJobId(flags, command);
  if (!id.ok()) return id.status();
  RoutedJob routed;
  if (std::optional<client::SplitJobId> split = client::SplitReplicaJobId(*id)) {
    absl::StatusOr<ServerFlags> server = ServerFlagsFrom(flags);
    if (!server.ok()) return server.status();
    routed.server = *std::move(server);
    routed.server.server = split->replica;
    routed.replica = split->replica;
    routed.job_id = split->job_id;
    return routed;
  }
  absl::StatusOr<ServerFlags> server = RequireServer(flags, command);
  if (!server.ok()) return server.status();
  if (client::NamesReplicas(server->server)) {
    return absl::InvalidArgumentError(absl::StrCat(
        command, ": job id '", *id,
        "' does not name its replica; with several servers give the id that --detach printed "
        "(HOST:PORT/JOBID)"));
  }
  routed.server = *std::move(server);
  routed.job_id = *id;
  return routed;
}

std::string AlgorithmName(const v1::JobSummary& job) {
  const InputKind input =
      job.input_kind() == v1::INPUT_KIND_POINTS_F32 ? InputKind::kPoints : InputKind::kMesh;
  const AlgorithmInfo* algorithm = FindAlgorithmByWire(
      input, job.algorithm() == v1::ALGORITHM_UNSPECIFIED ? v1::ALGORITHM_ML : job.algorithm());
  return algorithm != nullptr ? algorithm->name : absl::StrCat(job.algorithm());
}

int Watch(const Arguments& flags) {
  absl::StatusOr<RoutedJob> routed = RouteJob(flags, "watch");
  if (!routed.ok()) return Fail(routed.status());
  const std::string& full_id = flags.positional()[0];  // with its replica, if any
  const std::string& id = routed->job_id;
  const ServerFlags* server = &routed->server;
  absl::StatusOr<uint64_t> from_level = flags.GetUint("from-level", 0, UINT32_MAX);
  absl::StatusOr<uint64_t> clusters = flags.GetUint("clusters", 0, UINT32_MAX);
  for (const auto* value : {&from_level, &clusters}) {
    if (!value->ok()) return Fail(value->status());
  }
  if ((flags.has("labels") || flags.has("ply")) && *clusters == 0) {
    return Fail(absl::InvalidArgumentError("--labels and --ply need --clusters K (K >= 1)"));
  }
  if (flags.has("ply") != flags.has("mesh")) {
    return Fail(absl::InvalidArgumentError(
        "--ply FILE needs --mesh INPUT (the mesh file the job was submitted from)"));
  }
  if (absl::Status s = client::CheckClusteredMeshOutputs(std::nullopt, flags.value("ply"));
      !s.ok()) {
    return Fail(s);
  }
  // The mesh first: a wrong path fails before the watch starts.
  std::optional<TriangleMesh> mesh;
  if (flags.has("mesh")) {
    absl::StatusOr<TriangleMesh> read = ReadMeshFile(*flags.value("mesh"));
    if (!read.ok()) return Fail(read.status());
    mesh = *std::move(read);
  }
  absl::StatusOr<std::shared_ptr<grpc::Channel>> channel = ConnectTo(*server);
  if (!channel.ok()) return Fail(channel.status());

  const bool quiet = flags.has("quiet") || flags.has("json");
  client::WatchOptions options;
  options.from_level = *from_level;
  options.deadline = server->deadline;
  // The bar of mesh and points (client/progress_bar.h); the watcher does not know the
  // job's JobSpec.clusters, so the levels' share is reckoned down to one cluster.
  client::ProgressBarOptions progress_options;
  progress_options.mode = client::ProgressModeFor(stderr, quiet, flags.has("progress"));
  client::ProgressBar progress(stderr, progress_options);
  options.on_event = [&](const v1::JobEvent& event) { progress.Update(event); };
  options.on_resume = [&](const absl::Status& status) {
    if (!quiet) {
      std::fprintf(stderr, "mlclust: the stream broke (%s); resuming\n",
                   std::string(status.message()).c_str());
    }
  };
  const absl::Time started = absl::Now();
  absl::StatusOr<client::JobResult> result = client::WatchJob(*channel, id, options);
  const double seconds = absl::ToDoubleSeconds(absl::Now() - started);
  if (!result.ok() && !routed->replica.empty()) {
    result = client::ExplainReplicaFailure(result.status(), routed->replica, id);
  }
  if (!result.ok()) return Fail(ExplainDeadline(result.status(), *server, "the watch"));
  const HierarchyLog& log = result->hierarchy;
  if (mesh.has_value() && mesh->num_faces() != log.num_elements()) {
    return Fail(absl::InvalidArgumentError(absl::StrCat("--mesh: ", *flags.value("mesh"), " has ",
                                                        mesh->num_faces(), " faces; job ", id,
                                                        " has ", log.num_elements(), " elements")));
  }
  if (flags.has("levels-csv")) {
    if (absl::Status s = WriteLevelsCsv(flags.get("levels-csv"), log); !s.ok()) return Fail(s);
  }
  std::optional<size_t> level;
  if (*clusters > 0) {
    level = log.LastLevelWith(*clusters);
    if (!level.has_value()) level = log.FirstLevelWithAtMost(*clusters);
    if (!level.has_value()) {
      return Fail(absl::NotFoundError(absl::StrCat("no level received has ", *clusters,
                                                   " clusters or fewer (the last has ",
                                                   log.cluster_count(log.num_levels() - 1), ")")));
    }
    absl::StatusOr<std::vector<ClusterId>> labels = log.LabelsAt(*level);
    if (!labels.ok()) return Fail(labels.status());
    const std::vector<uint32_t> compact = client::CompactLabels(*labels);
    if (flags.has("labels")) {
      if (absl::Status s = WriteLabels(flags.get("labels"), compact); !s.ok()) return Fail(s);
    }
    if (mesh.has_value()) {
      std::vector<ClusterId> ids(compact.size());
      for (size_t i = 0; i < compact.size(); ++i) ids[i] = ClusterId(compact[i]);
      if (absl::Status s = WriteClusteredPly(*flags.value("ply"), *mesh, ids); !s.ok()) {
        return Fail(s);
      }
    }
  }
  const v1::Done& done = result->done;
  if (flags.has("json")) {
    std::string json = absl::StrCat(
        R"({"job_id": )", JsonString(full_id), R"(, "elements": )", log.num_elements(),
        R"(, "first_level": )", result->first_level, R"(, "levels": )", log.num_levels(),
        R"(, "triplets": )", log.num_moves(), R"(, "final_clusters": )", done.final_clusters(),
        R"(, "device": )", JsonString(done.device()), R"(, "devices": )", DevicesJson(done),
        R"(, "seconds": )", absl::StrFormat("%.4f", seconds));
    if (level.has_value()) {
      absl::StrAppend(&json, R"(, "level": {"index": )", result->first_level + *level,
                      R"(, "clusters": )", log.cluster_count(*level), R"(, "energy": )",
                      std::isfinite(log.energy(*level))
                          ? absl::StrFormat("%.17g", log.energy(*level))
                          : std::string("null"),
                      "}");
    }
    std::printf("%s}\n", json.c_str());
    return 0;
  }
  std::string level_note;
  if (level.has_value()) {
    level_note =
        absl::StrFormat("; level %zu: %u clusters, energy %.10g", result->first_level + *level,
                        log.cluster_count(*level), log.energy(*level));
  }
  std::printf("%s: %zu elements, levels %u to %zu, %zu triplets in %.3f s %s%s\n", full_id.c_str(),
              log.num_elements(), result->first_level, result->first_level + log.num_levels() - 1,
              log.num_moves(), seconds, DevicesSummary(done).c_str(), level_note.c_str());
  return 0;
}

int Cancel(const Arguments& flags) {
  absl::StatusOr<RoutedJob> routed = RouteJob(flags, "cancel");
  if (!routed.ok()) return Fail(routed.status());
  const ServerFlags& server = routed->server;
  absl::StatusOr<std::shared_ptr<grpc::Channel>> channel = ConnectTo(server);
  if (!channel.ok()) return Fail(channel.status());
  absl::StatusOr<std::string> state = client::CancelJob(
      *channel, routed->job_id,
      server.deadline == absl::InfiniteDuration() ? absl::Seconds(30) : server.deadline);
  if (!state.ok() && !routed->replica.empty()) {
    state = client::ExplainReplicaFailure(state.status(), routed->replica, routed->job_id);
  }
  if (!state.ok()) return Fail(ExplainDeadline(state.status(), server, "the cancel"));
  if (flags.has("json")) {
    std::printf("{\"job_id\": %s, \"state\": %s}\n", JsonString(flags.positional()[0]).c_str(),
                JsonString(*state).c_str());
  } else {
    std::printf("%s: %s\n", flags.positional()[0].c_str(), state->c_str());
  }
  return 0;
}

int Jobs(const Arguments& flags) {
  if (!flags.positional().empty()) {
    return Fail(absl::InvalidArgumentError("jobs: takes no positional arguments"));
  }
  absl::StatusOr<ServerFlags> server = RequireServer(flags, "jobs");
  if (!server.ok()) return Fail(server.status());
  const absl::Duration deadline =
      server->deadline == absl::InfiniteDuration() ? absl::Seconds(30) : server->deadline;
  absl::StatusOr<v1::JobList> list;
  if (client::NamesReplicas(server->server)) {
    // Several replicas: every one's jobs, their ids naming the replica; a replica that does
    // not answer is named on stderr (the exit code says whether any did).
    absl::StatusOr<std::vector<std::string>> replicas = client::ResolveReplicas(server->server);
    if (!replicas.ok()) return Fail(replicas.status());
    list = v1::JobList();
    bool any = false;
    for (const std::string& replica : *replicas) {
      absl::StatusOr<std::shared_ptr<grpc::Channel>> channel =
          client::Connect(replica, server->connect);
      if (!channel.ok()) return Fail(channel.status());
      absl::StatusOr<v1::JobList> one = client::ListJobs(*channel, deadline);
      if (!one.ok()) {
        std::fprintf(stderr, "mlclust: replica %s: %s\n", replica.c_str(),
                     std::string(one.status().message()).c_str());
        continue;
      }
      any = true;
      for (v1::JobSummary& job : *one->mutable_jobs()) {
        job.set_job_id(client::ReplicaJobId(replica, job.job_id()));
        *list->add_jobs() = std::move(job);
      }
    }
    if (!any) return Fail(absl::UnavailableError("jobs: no replica answered"));
  } else {
    absl::StatusOr<std::shared_ptr<grpc::Channel>> channel = ConnectTo(*server);
    if (!channel.ok()) return Fail(channel.status());
    list = client::ListJobs(*channel, deadline);
  }
  if (!list.ok()) return Fail(ExplainDeadline(list.status(), *server, "the list"));
  if (flags.has("json")) {
    std::printf("%s", MessageJson(*list).c_str());
    return 0;
  }
  int id_width = 12;  // replica ids (HOST:PORT/JOBID) are longer
  for (const v1::JobSummary& job : list->jobs()) {
    id_width = std::max(id_width, static_cast<int>(job.job_id().size()));
  }
  std::printf("%-*s %-10s %-9s %-8s %7s %10s %9s %9s  %s\n", id_width, "JOB", "STATE", "ALGO",
              "DETACHED", "LEVELS", "TRIPLETS", "QUEUED_S", "RUN_S", "LABEL / MESSAGE");
  for (const v1::JobSummary& job : list->jobs()) {
    std::string note = job.label();
    if (job.state() == "failed" || job.state() == "cancelled") {
      absl::StrAppend(&note, note.empty() ? "" : ": ", job.message());
    }
    std::printf("%-*s %-10s %-9s %-8s %7u %10llu %9.2f %9.2f  %s\n", id_width, job.job_id().c_str(),
                job.state().c_str(), AlgorithmName(job).c_str(), job.detached() ? "yes" : "no",
                job.levels(), static_cast<unsigned long long>(job.triplets()), job.seconds_queued(),
                job.seconds_running(), note.c_str());
  }
  return 0;
}

}  // namespace

absl::StatusOr<ServerFlags> ServerFlagsFrom(const Arguments& args) {
  auto get = [&](const std::string& name) { return args.value(name); };
  ServerFlags flags;
  flags.server = get("server").value_or("");
  flags.connect.tls_ca_file = get("tls-ca").value_or("");
  flags.connect.tls_cert_file = get("tls-cert").value_or("");
  flags.connect.tls_key_file = get("tls-key").value_or("");
  flags.connect.auth_token_file = get("auth-token-file").value_or("");
  if (std::optional<std::string> deadline = get("deadline")) {
    double seconds = 0;
    if (!absl::SimpleAtod(*deadline, &seconds) || !(seconds > 0) || seconds > 1e7) {
      return absl::InvalidArgumentError(
          absl::StrCat("--deadline: '", *deadline, "' is not a number of seconds > 0"));
    }
    flags.deadline = absl::Seconds(seconds);
  }
  if (std::optional<std::string> spread = get("spread")) {
    if (*spread != "least-loaded" && *spread != "in-order") {
      return absl::InvalidArgumentError(
          absl::StrCat("--spread: '", *spread, "' is not least-loaded or in-order"));
    }
    flags.spread_in_order = *spread == "in-order";
  }
  if (std::optional<std::string> resubmit = get("resubmit")) {
    int n = 0;
    if (!absl::SimpleAtoi(*resubmit, &n) || n < 0 || n > 100) {
      return absl::InvalidArgumentError(
          absl::StrCat("--resubmit: '", *resubmit, "' is not a number of tries in 0-100"));
    }
    flags.max_resubmits = n;
  }
  return flags;
}

client::ReplicaOptions ReplicaOptionsFrom(const ServerFlags& flags, bool quiet) {
  client::ReplicaOptions options;
  options.connect = flags.connect;
  options.in_order = flags.spread_in_order;
  options.max_resubmits = flags.max_resubmits;
  if (quiet) return options;
  options.on_retry = [](const std::string& replica, const absl::Status& status) {
    std::fprintf(stderr, "mlclust: replica %s did not accept the job (%s); trying another\n",
                 replica.c_str(), std::string(status.message()).c_str());
  };
  options.on_resubmit = [](const client::Resubmission& lost) {
    // On a terminal, after the progress line (job_cli.cc's, which rewrites its line).
    std::fprintf(stderr,
                 "%smlclust: replica %s accepted the job and then became unreachable (%s); "
                 "submitting it again to the next replica (try %d of %d), keeping the %zu "
                 "levels received\n",
                 isatty(STDERR_FILENO) ? "\n" : "", lost.lost_replica.c_str(),
                 std::string(lost.status.message()).c_str(), lost.attempt, lost.max_resubmits,
                 lost.levels_kept);
  };
  return options;
}

absl::StatusOr<std::shared_ptr<grpc::Channel>> ConnectTo(const ServerFlags& flags) {
  return client::Connect(flags.server, flags.connect);
}

absl::Status ExplainDeadline(const absl::Status& status, const ServerFlags& flags,
                             const std::string& what) {
  if (status.code() != absl::StatusCode::kDeadlineExceeded ||
      flags.deadline == absl::InfiniteDuration()) {
    return status;
  }
  std::string after = what == "the job" ? "; the server cancelled the job"
                      : what == "the watch"
                          ? "; the job itself runs on (watch it again, or `mlclust cancel` it)"
                          : "";
  return absl::DeadlineExceededError(absl::StrCat(what, " did not finish within --deadline ",
                                                  absl::FormatDuration(flags.deadline), after,
                                                  " (gRPC: ", status.message(), ")"));
}

int SubmitDetachedCommand(const ServerFlags& flags, const v1::JobSpec& spec,
                          const std::string& payload, bool quiet) {
  if (flags.server.empty()) {
    return Fail(absl::InvalidArgumentError(
        "--detach needs --server ADDR: an embedded server ends with this command"));
  }
  client::RunOptions options;
  options.deadline = flags.deadline;
  if (client::NamesReplicas(flags.server)) {
    // Several replicas: the id printed names the one that accepted the job.
    absl::StatusOr<std::vector<std::string>> replicas = client::ResolveReplicas(flags.server);
    if (!replicas.ok()) return Fail(replicas.status());
    const client::ReplicaOptions replica_options = ReplicaOptionsFrom(flags, quiet);
    std::string replica;
    absl::StatusOr<v1::Accepted> accepted = client::SubmitDetachedOnReplicas(
        *replicas, spec, payload, options, replica_options, &replica);
    if (!accepted.ok()) return Fail(ExplainDeadline(accepted.status(), flags, "the upload"));
    if (!quiet) {
      std::printf(
          "queued on replica %s (%u jobs ahead); results kept %.0f s after it ends; `mlclust "
          "watch %s`\n",
          replica.c_str(), accepted->queue_position(), accepted->retention_seconds(),
          accepted->job_id().c_str());
    }
    std::printf("%s\n", accepted->job_id().c_str());
    return 0;
  }
  absl::StatusOr<std::shared_ptr<grpc::Channel>> channel = ConnectTo(flags);
  if (!channel.ok()) return Fail(channel.status());
  absl::StatusOr<v1::Accepted> accepted = client::SubmitDetached(*channel, spec, payload, options);
  if (!accepted.ok()) return Fail(ExplainDeadline(accepted.status(), flags, "the upload"));
  if (!quiet) {
    std::printf(
        "queued on %s (%u jobs ahead); results kept %.0f s after it ends; `mlclust watch "
        "%s --server %s`\n",
        flags.server.c_str(), accepted->queue_position(), accepted->retention_seconds(),
        accepted->job_id().c_str(), flags.server.c_str());
  }
  std::printf("%s\n", accepted->job_id().c_str());
  return 0;
}

// The rows of watch, cancel and jobs; --server and the connection flags follow.
Command WatchCommand() {
  return {
      ServerCommandLine(
          "watch",
          "JOB --server ADDR [--from-level N] [--clusters K] [--labels FILE]\n"
          "                    [--levels-csv FILE] [--ply FILE --mesh INPUT] [--quiet] [--json]",
          "Streams a job's levels (detached or not: every job's are kept; `jobs` lists the "
          "ids), while it runs or after it ended, from any client of its tenant: a snapshot "
          "of level N, then every level after it. A stream that breaks is resumed where it "
          "stopped. NOT_FOUND once the server has dropped the job's results (the message "
          "says when and why).",
          kJobServerHelp,
          {{"from-level", "N", "the first level sent, as a snapshot (default 0, the job's first)"},
           {"clusters", "K", "the level written by --labels and --ply", 'k'},
           {"labels", "FILE", "one line per element: its cluster (0..K-1) at that level", 'o'},
           {"levels-csv", "FILE", "a row \"clusters,energy\" per level received"},
           {"ply", "FILE", "the mesh INPUT with one colour per cluster at that level"},
           {"mesh", "INPUT", "the mesh file the job was submitted from (for --ply)"},
           {"quiet", "", "no progress on stderr", 'q'},
           {"progress", "", "progress lines on stderr even when it is not a terminal"},
           {"json", "", "print the summary as one JSON object"}}),
      Watch};
}

Command CancelCommand() {
  return {ServerCommandLine("cancel", "JOB --server ADDR",
                            "Cancels a queued or running job; prints its state.", kJobServerHelp,
                            {{"json", "", "print the job id and state as JSON"}, kNoProgressRow}),
          Cancel};
}

Command JobsCommand() {
  return {ServerCommandLine("jobs", "--server ADDR [--json]",
                            "The jobs of this client's tenant on the server: queued, running, and "
                            "those ended within the retention time, with their state, levels and "
                            "times.",
                            "the server, or several (their jobs' ids name the replica)",
                            {{"json", "", "print the list as JSON"}, kNoProgressRow}),
          Jobs};
}

}  // namespace mlclust::cli
