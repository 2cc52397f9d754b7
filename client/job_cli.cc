#include "client/job_cli.h"

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_replace.h"
#include "absl/time/clock.h"
#include "client/job_commands.h"
#include "client/replicas.h"
#include "core/base/status_macros.h"
#include "core/plan/device_policy.h"
#include "grpcpp/grpcpp.h"
#include "server/job_options.h"
#include "server/server.h"
#ifdef MLCLUST_HAVE_PLOT
#include "client/plot.h"
#endif
#include "client/progress_bar.h"

namespace mlclust::cli {
namespace {

std::string JsonList(const google::protobuf::RepeatedField<uint32_t>& values) {
  return absl::StrCat("[", absl::StrJoin(values, ", "), "]");
}

// --plot FILE.png: every level received (clusters, energy), the server's elbows marked.
absl::Status WritePlot(const std::string& path, const HierarchyLog& log, const v1::Done& done,
                       const std::string& title, uint32_t chosen) {
#ifdef MLCLUST_HAVE_PLOT
  std::vector<client::EnergyCurvePoint> curve;
  std::set<uint32_t> counts;
  for (size_t l = 0; l < log.num_levels(); ++l) {
    curve.push_back({log.cluster_count(l), log.energy(l)});
    counts.insert(log.cluster_count(l));
  }
  client::EnergyPlotOptions options;
  options.title = title;
  // The server finds the elbows over every level it made; a level range may leave some out.
  for (uint32_t k : done.elbow_cluster_counts()) {
    if (counts.contains(k)) options.elbows.push_back(k);
  }
  if (counts.contains(chosen)) options.chosen = chosen;
  absl::Status status = client::WriteEnergyPlotPng(curve, options, path);
  if (!status.ok()) return absl::Status(status.code(), absl::StrCat("--plot: ", status.message()));
  return absl::OkStatus();
#else
  (void)log;
  (void)done;
  (void)title;
  (void)chosen;
  return absl::UnimplementedError(absl::StrCat(
      "--plot ", path, ": this mlclust was built without cairo (libcairo2-dev); no plot"));
#endif
}

}  // namespace

std::string DevicesJson(const v1::Done& done) {
  std::vector<std::string> stages;
  for (const v1::StageRan& stage : done.devices()) {
    stages.push_back(absl::StrCat(JsonString(stage.stage()), ": ", JsonString(stage.device())));
  }
  return absl::StrCat("{", absl::StrJoin(stages, ", "), "}");
}

std::string DevicesSummary(const v1::Done& done) {
  std::vector<std::string> on_cpu, elsewhere;
  std::set<std::string> devices;
  for (const v1::StageRan& stage : done.devices()) {
    devices.insert(stage.device());
    (stage.device() == "cpu" ? on_cpu : elsewhere)
        .push_back(absl::StrCat(stage.stage(), " on ", stage.device()));
  }
  if (devices.empty()) return absl::StrCat("on ", done.device());
  if (devices.size() == 1) return absl::StrCat("on ", *devices.begin());
  on_cpu.insert(on_cpu.end(), elsewhere.begin(), elsewhere.end());
  return absl::StrCat("with ", absl::StrJoin(on_cpu, ", "));
}

bool HardwareGpuDevicePresent() {
  std::error_code error;
  if (std::filesystem::exists("/dev/nvidiactl", error)) return true;
  if (std::filesystem::exists("/dev/dxg", error)) return true;  // WSL2's GPU (Mesa d3d12)
  for (const std::filesystem::directory_entry& entry :
       std::filesystem::directory_iterator("/dev/dri", error)) {
    if (entry.path().filename().string().starts_with("renderD")) return true;
  }
  return false;
}

server::ServerOptions EmbeddedServerOptions(const Arguments& args) {
  server::ServerOptions options;
  options.log = false;
  // It ends with this command, so no other client can watch its jobs: it keeps no copy of
  // their levels.
  options.kept_results_bytes = 0;
  // A job whose stages all run on the CPU and that draws no preview needs no GL context,
  // whose creation (EGL loading Mesa's driver and LLVM) cost 0.08-0.10 s of CPU, ~6% of an
  // ML run on bunny00: the device policy says which (a bad --device is the server's to
  // refuse).
  const absl::StatusOr<DeviceChoice> device = ParseDeviceChoice(args.get("device", "auto"));
  if (!args.has("preview") && device.ok() && !MayUseGpu(*device, HardwareGpuDevicePresent())) {
    options.gpu = server::GpuMode::kOff;
  }
  return options;
}

// --server ADDR: HOST:PORT (a name, IPv4 or [IPv6]) with a port in 1..65535,
// or a gRPC URI (unix:PATH, dns:///HOST:PORT, ...) passed as it is.
absl::Status CheckServerAddress(const std::string& address) {
  if (client::NamesReplicas(address)) {
    // Several replicas (client/replicas.h): each item is checked, a dns:
    // name resolved.
    return client::ResolveReplicas(address).status();
  }
  if (absl::StrContains(address, ":/") || absl::StartsWith(address, "unix:")) {
    return absl::OkStatus();
  }
  const size_t colon = address.rfind(':');
  uint32_t port = 0;
  if (colon == std::string::npos || colon == 0 ||
      !absl::SimpleAtoi(address.substr(colon + 1), &port) || port < 1 || port > 65535) {
    return absl::InvalidArgumentError(absl::StrCat(
        "--server: '", address, "' is not an address: give HOST:PORT (port 1-65535), e.g. ",
        "127.0.0.1:50051"));
  }
  return absl::OkStatus();
}

// A failed call to the server at `address`, in plain words where gRPC's text
// is about the connection (the original text follows for the record).
absl::Status PlainConnectionError(const absl::Status& status, const std::string& address) {
  const std::string text(status.message());
  std::string plain;
  if (absl::StrContains(text, "Connection refused")) {
    plain = absl::StrCat("no server is listening at ", address,
                         " (connection refused): is `mlclust serve` running "
                         "there, on this port?");
  } else if (absl::StrContains(text, "DNS resolution failed") ||
             absl::StrContains(text, "Domain name not found")) {
    plain = absl::StrCat("cannot find the host of ", address,
                         " (DNS: no such name): check the address, HOST:PORT");
  } else if (absl::StrContains(text, "Failed parsing HTTP/2") ||
             absl::StrContains(text, "Socket closed") ||
             absl::StrContains(text, "Connection reset") || absl::StrContains(text, "handshake") ||
             absl::StrContains(text, "SSL") || absl::StrContains(text, "ssl")) {
    plain = absl::StrCat("something answers at ", address,
                         ", but not an mlclust server speaking plain gRPC: "
                         "a wrong port, or a "
                         "TLS endpoint (this client speaks plaintext)?");
  } else if (status.code() == absl::StatusCode::kDeadlineExceeded &&
             absl::StrContains(text, "connect")) {
    plain = absl::StrCat("no answer from ", address,
                         " in time: a firewall, a wrong host, or a wrong port?");
  } else if (status.code() == absl::StatusCode::kUnimplemented &&
             absl::StrContains(text, "GetServerInfo")) {
    plain = absl::StrCat("the server at ", address,
                         " does not answer GetServerInfo (an older mlclust server)");
  }
  if (plain.empty()) return status;
  return absl::Status(status.code(), absl::StrCat(plain, "\n  (gRPC: ", text, ")"));
}

absl::StatusOr<std::string> ReadFileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return absl::NotFoundError(absl::StrCat("cannot open ", path));
  std::ostringstream bytes;
  bytes << in.rdbuf();
  return bytes.str();
}

absl::Status WriteLevelsCsv(const std::string& path, const HierarchyLog& log) {
  std::FILE* out = std::fopen(path.c_str(), "w");
  if (out == nullptr) return absl::UnavailableError(absl::StrCat("cannot write ", path));
  std::fputs("clusters,energy\n", out);
  for (size_t l = 0; l < log.num_levels(); ++l) {
    std::fprintf(out, "%u,%.17g\n", log.cluster_count(l), log.energy(l));
  }
  if (std::fclose(out) != 0) return absl::UnavailableError(absl::StrCat("cannot write ", path));
  return absl::OkStatus();
}

absl::Status WriteLabels(const std::string& path, std::span<const uint32_t> labels) {
  std::FILE* out = std::fopen(path.c_str(), "w");
  if (out == nullptr) return absl::UnavailableError(absl::StrCat("cannot write ", path));
  for (uint32_t label : labels) std::fprintf(out, "%u\n", label);
  if (std::fclose(out) != 0) return absl::UnavailableError(absl::StrCat("cannot write ", path));
  return absl::OkStatus();
}

// --detach: the job is submitted and its id printed; watch it with `mlclust
// watch`.
int Detach(const Arguments& args, const v1::JobSpec& spec, const std::string& payload) {
  absl::StatusOr<ServerFlags> flags = ServerFlagsFrom(args);
  if (!flags.ok()) return Fail(flags.status());
  for (const char* output : {"labels", "levels-csv", "ply", "out", "coarse", "json", "auto-k",
                             "plot", "repair", "preview"}) {
    if (args.has(output)) {
      return Fail(absl::InvalidArgumentError(absl::StrCat(
          "--detach returns before the job runs: --", output, " goes to `mlclust watch JOB`")));
    }
  }
  if (args.has("server")) {
    if (absl::Status s = CheckServerAddress(args.get("server")); !s.ok()) return Fail(s);
  }
  return SubmitDetachedCommand(*flags, spec, payload, args.has("quiet"));
}

// Runs `spec` on the server --server names, or on one started inside this
// process, with a progress line on a terminal. `labels_for_clusters`: the K
// of --clusters, whose level's labels the client rebuilds while the stream
// arrives (RunOptions::labels_for_clusters; LabelsOfLevel).
absl::StatusOr<client::JobResult> RunOnServer(const Arguments& args, const v1::JobSpec& spec,
                                              const std::string& payload, double* seconds,
                                              v1::Accepted* accepted,
                                              uint32_t labels_for_clusters) {
  std::unique_ptr<server::Server> embedded;
  std::shared_ptr<grpc::Channel> channel;
  MLCLUST_ASSIGN_OR_RETURN(const ServerFlags flags, ServerFlagsFrom(args));
  if (args.has("server")) {
    MLCLUST_RETURN_IF_ERROR(CheckServerAddress(args.get("server")));
    if (!client::NamesReplicas(args.get("server"))) {
      MLCLUST_ASSIGN_OR_RETURN(channel, ConnectTo(flags));
    }
  } else {
    absl::StatusOr<std::unique_ptr<server::Server>> started =
        server::Server::Start(EmbeddedServerOptions(args));
    if (!started.ok()) return started.status();
    embedded = *std::move(started);
    channel = embedded->InProcessChannel();
  }
  client::ProgressBarOptions progress_options;
  progress_options.mode = client::ProgressModeFor(stderr, args.has("quiet"), args.has("progress"));
  progress_options.final_clusters = std::max({1u, spec.clusters(), spec.levels_low()});
  client::ProgressBar progress(stderr, progress_options);
  client::RunOptions run_options;
  run_options.on_event = [&](const v1::JobEvent& event) {
    if (event.has_accepted() && accepted != nullptr) *accepted = event.accepted();
    progress.Update(event);
  };
  run_options.deadline = flags.deadline;
  run_options.labels_for_clusters = labels_for_clusters;
  const absl::Time started_at = absl::Now();
  if (args.has("server") && client::NamesReplicas(args.get("server"))) {
    // Several replicas: the least loaded first, the next where one did not
    // accept the job.
    MLCLUST_ASSIGN_OR_RETURN(const std::vector<std::string> replicas,
                             client::ResolveReplicas(args.get("server")));
    const client::ReplicaOptions replica_options = ReplicaOptionsFrom(flags, args.has("quiet"));
    std::string replica;
    absl::StatusOr<client::JobResult> result =
        client::RunJobOnReplicas(replicas, spec, payload, run_options, replica_options, &replica);
    *seconds = absl::ToDoubleSeconds(absl::Now() - started_at);
    if (!result.ok()) return ExplainDeadline(result.status(), flags, "the job");
    return result;
  }
  absl::StatusOr<client::JobResult> result = client::RunJob(channel, spec, payload, run_options);
  *seconds = absl::ToDoubleSeconds(absl::Now() - started_at);
  if (!result.ok()) result = ExplainDeadline(result.status(), flags, "the job");
  if (!result.ok() && args.has("server")) {
    return PlainConnectionError(result.status(), args.get("server"));
  }
  return result;
}

absl::Status WriteLevelOutputs(const Arguments& args, const client::JobResult& result,
                               size_t elements, const std::string& element_name,
                               const std::string& plot_title) {
  const HierarchyLog& log = result.hierarchy;
  if (log.num_elements() != elements) {
    return absl::DataLossError(absl::StrCat("the server sent labels for ", log.num_elements(), " ",
                                            element_name, "; the input has ", elements));
  }
  if (args.has("levels-csv")) {
    MLCLUST_RETURN_IF_ERROR(WriteLevelsCsv(args.get("levels-csv"), log));
  }
  if (args.has("plot")) {
    // The level the command writes: --clusters K (the level ChooseLevel picks), or the
    // one --auto-k picks (the first elbow, or the highest BIC).
    uint32_t chosen = 0;
    const std::string auto_k = args.get("auto-k", "");
    absl::StatusOr<uint64_t> clusters = args.GetUint("clusters", 0, UINT32_MAX);
    if (auto_k == "elbow" && !result.done.elbow_cluster_counts().empty()) {
      chosen = result.done.elbow_cluster_counts(0);
    } else if (auto_k == "bic") {
      chosen = result.done.bic_best_cluster_count();
    } else if (auto_k.empty() && clusters.ok() && *clusters > 0) {
      absl::StatusOr<size_t> level = ChooseLevel(log, static_cast<uint32_t>(*clusters));
      if (level.ok()) chosen = log.cluster_count(*level);
    }
    MLCLUST_RETURN_IF_ERROR(WritePlot(args.get("plot"), log, result.done, plot_title, chosen));
  }
  return absl::OkStatus();
}

std::vector<FlagGroup> JobFlagGroups(InputKind input, const std::vector<Flag>& own) {
  std::vector<Flag> flags = {
      {"server", "ADDR",
       "the server (HOST:PORT, a gRPC URI, or several: see --spread); without it the server "
       "runs inside this process"},
      AlgorithmFlag(input)};
  flags.insert(flags.end(), own.begin(), own.end());
  flags.insert(
      flags.end(),
      {{"levels", "K_HI:K_LO",
        "hierarchies: only the levels with K_LO..K_HI clusters (a snapshot, then deltas)"},
       {"seed", "S", "random seed (default 1)"},
       {"device", "D",
        "auto (default): the GPU for the stages that have a GPU implementation where it is "
        "hardware and the job fits its memory; gpu: there even on a software renderer (a stage "
        "the GPU does not cover runs on the CPU and the job says why; refused where no stage "
        "can, or the job does not fit); cpu: every stage on the CPU"},
       {"detach", "",
        "submit the job to --server and return as soon as it is queued; the job id is the last "
        "line of stdout (`mlclust watch JOB` streams its levels). The server keeps the job's "
        "levels for its retention time (serve --retention-seconds)"},
       {"quiet", "", "no progress on stderr", 'q'},
       {"progress", "",
        "progress on stderr even when it is not a terminal: a line at every tenth done (on a "
        "terminal a bar with the share done and the time left is the default)"},
       {"json", "", "print the job summary as one JSON object"}});
  std::vector<FlagGroup> groups = {{"", std::move(flags)}};
  for (FlagGroup& group : RegistryOptionGroups(input)) groups.push_back(std::move(group));
  groups.push_back(ConnectionFlags());
  return groups;
}

// The level --clusters K writes: the last level with exactly K clusters (a
// single-level algorithm's result follows its start at the same K), else the
// first with fewer (PML may skip counts).
absl::StatusOr<size_t> ChooseLevel(const HierarchyLog& log, uint32_t k) {
  std::optional<size_t> level = log.LastLevelWith(k);
  if (!level.has_value()) level = log.FirstLevelWithAtMost(k);
  if (!level.has_value()) {
    return absl::NotFoundError(absl::StrCat("no level has ", k, " clusters or fewer (the last has ",
                                            log.cluster_count(log.num_levels() - 1), ")"));
  }
  return *level;
}

// The labels at `level`: those the client rebuilt as the stream arrived
// where it chose the same level (RunOptions::labels_for_clusters, taken from
// `result`), else replayed from level 0. The same labels either way.
absl::StatusOr<std::vector<ClusterId>> LabelsOfLevel(client::JobResult& result, size_t level) {
  if (result.chosen_level == level) return std::move(result.chosen_labels);
  return result.hierarchy.LabelsAt(level);
}

std::string ElbowNote(const v1::Done& done) {
  std::string elbows;
  for (uint32_t k : done.elbow_cluster_counts()) {
    absl::StrAppend(&elbows, elbows.empty() ? "; elbows at " : ", ", k);
  }
  return elbows;
}

// The job summary as one JSON object (--json): what ran, where, what came
// back, and the level written.
std::string SummaryJson(const Arguments& args, const std::string& input,
                        const std::string& element_name, size_t elements,
                        const AlgorithmInfo& algorithm, const v1::JobSpec& spec,
                        const HierarchyLog& log, double seconds, const v1::Done& done,
                        std::optional<size_t> level, const std::string& auto_k,
                        const std::set<std::string>& not_written) {
  const EnergyInfo* energy = FindEnergyByWire(algorithm.input, spec.energy());
  const std::string energy_name = energy != nullptr ? energy->name : algorithm.energies[0];
  std::string json = absl::StrCat(
      "{\"input\": ", JsonString(input), ", \"", element_name, "\": ", elements,
      ", \"algorithm\": ", JsonString(algorithm.name), ", \"energy\": ", JsonString(energy_name),
      ", \"server\": ", JsonString(args.has("server") ? args.get("server") : "embedded"),
      ", \"device\": ", JsonString(done.device()), ", \"devices\": ", DevicesJson(done),
      ", \"seconds\": ", absl::StrFormat("%.4f", seconds), ", \"levels\": ", log.num_levels(),
      ", \"triplets\": ", log.num_moves(), ", \"final_clusters\": ", done.final_clusters(),
      ", \"elbows\": ", JsonList(done.elbow_cluster_counts()));
  if (algorithm.input == InputKind::kPoints && algorithm.hierarchy) {
    absl::StrAppend(&json, ", \"bic_best_clusters\": ", done.bic_best_cluster_count(),
                    ", \"bic_first_decrease_clusters\": ", done.bic_first_decrease_cluster_count(),
                    ", \"bic_merging_first_decrease_clusters\": ",
                    done.bic_merging_first_decrease_cluster_count());
  }
  if (!auto_k.empty()) absl::StrAppend(&json, ", \"auto_k\": ", JsonString(auto_k));
  if (level.has_value()) {
    absl::StrAppend(&json, R"(, "level": {"index": )", *level,
                    ", \"clusters\": ", log.cluster_count(*level),
                    ", \"energy\": ", JsonNumber(log.energy(*level)), "}");
  } else {
    absl::StrAppend(&json, ", \"level\": null");
  }
  std::vector<std::string> outputs;
  // Keyed by the flag's name in the summary's one style, snake_case ("levels_csv").
  for (const char* name : {"labels", "levels-csv", "ply", "out", "coarse", "plot", "preview"}) {
    if (args.has(name) && !not_written.contains(name)) {
      outputs.push_back(absl::StrCat(JsonString(absl::StrReplaceAll(name, {{"-", "_"}})), ": ",
                                     JsonString(args.get(name))));
    }
  }
  absl::StrAppend(&json, ", \"outputs\": {", absl::StrJoin(outputs, ", "), "}}");
  return json;
}

// --levels K_HI:K_LO (either end may be empty): the levels with cluster
// counts in [K_LO, K_HI].
absl::Status SetLevels(const Arguments& args, bool hierarchy, v1::JobSpec& spec) {
  if (!args.has("levels")) return absl::OkStatus();
  const std::string range = args.get("levels");
  const size_t colon = range.find(':');
  uint32_t high = 0, low = 0;
  const std::string high_text = range.substr(0, colon);
  const std::string low_text = colon == std::string::npos ? "" : range.substr(colon + 1);
  if (!hierarchy || colon == std::string::npos ||
      (!high_text.empty() && !absl::SimpleAtoi(high_text, &high)) ||
      (!low_text.empty() && !absl::SimpleAtoi(low_text, &low))) {
    return absl::InvalidArgumentError(
        "--levels: give K_HI:K_LO (cluster counts) with a hierarchy (--algo "
        "hc, ml, pml or "
        "bisecting)");
  }
  spec.set_levels_high(high);
  spec.set_levels_low(low);
  return absl::OkStatus();
}

// The wire energy from --energy (through the registry; not given: the
// algorithm's default).
absl::Status SetEnergy(const Arguments& args, InputKind input, v1::JobSpec& spec) {
  if (!args.has("energy")) return absl::OkStatus();
  const std::string name = args.get("energy");
  const EnergyInfo* energy = FindEnergy(input, name);
  if (energy == nullptr) {
    return absl::InvalidArgumentError(
        absl::StrCat("--energy: '", name, "' is not one of ", EnergyNames(input)));
  }
  if (energy->wire == 0) {
    return absl::UnimplementedError(
        absl::StrCat("--energy: ", name, " is not on the wire yet (only `mlclust energy` has it)"));
  }
  spec.set_energy(static_cast<v1::Energy>(energy->wire));
  return absl::OkStatus();
}

// The algorithm from --algo (through the registry; not given: ML).
absl::StatusOr<const AlgorithmInfo*> GetAlgorithm(const Arguments& args, InputKind input) {
  if (!args.has("algo")) return &DefaultAlgorithm(input);
  const std::string name = args.get("algo");
  const AlgorithmInfo* algorithm = FindAlgorithm(input, name);
  if (algorithm == nullptr) {
    return absl::InvalidArgumentError(
        absl::StrCat("--algo: '", name, "' is not one of ", AlgorithmNames(input)));
  }
  return algorithm;
}

// Every registry option of `input` given on the command line travels as
// text: the server checks it against the algorithm and names any that is
// unknown or out of range.
void SetOptions(const Arguments& args, InputKind input, v1::JobSpec& spec) {
  for (const std::string& name : RegistryOptionNames(input)) {
    if (args.has(name)) (*spec.mutable_options())[name] = args.get(name);
  }
}

// --energy (default cvd; every mesh energy, also those not on the wire) and
// its options.
absl::StatusOr<MeshEnergyOptions> EnergyFromArguments(const Arguments& args,
                                                      const std::string& default_name) {
  const std::string name = args.get("energy", default_name);
  const EnergyInfo* energy = FindEnergy(InputKind::kMesh, name);
  if (energy == nullptr) {
    return absl::InvalidArgumentError(
        absl::StrCat("--energy: '", name, "' is not one of ", EnergyNames(InputKind::kMesh)));
  }
  JobPlan plan;
  plan.mesh_energy.kind = energy->mesh_kind;
  for (const OptionInfo& option : EnergyOptions()) {
    if (!args.has(option.name)) continue;
    absl::StatusOr<OptionValue> value = ParseOptionValue(option, args.get(option.name));
    if (!value.ok()) return value.status();
    option.apply(*value, plan);
  }
  MLCLUST_RETURN_IF_ERROR(ValidateMeshEnergyOptions(plan.mesh_energy));
  return plan.mesh_energy;
}

}  // namespace mlclust::cli
