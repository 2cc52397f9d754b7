// `mlclust energy` (a labelling's energy from the mesh file), `mlclust stats` and
// `mlclust info` (what a server is, runs and is doing).
#include <cstdio>
#include <fstream>

#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/time/clock.h"
#include "client/commands.h"
#include "client/job_cli.h"
#include "client/job_commands.h"
#include "client/replicas.h"
#include "core/base/status_macros.h"
#include "core/io/prepare_mesh.h"
#include "google/protobuf/text_format.h"
#include "grpcpp/grpcpp.h"
#include "mlclust/v1/mlclust.grpc.pb.h"
#include "server/job_options.h"
#include "server/server.h"

namespace mlclust::cli {
namespace {

absl::StatusOr<std::vector<ClusterId>> ReadLabels(const std::string& path, size_t expected) {
  std::ifstream in(path);
  if (!in) return absl::NotFoundError(absl::StrCat("cannot open ", path));
  std::vector<ClusterId> labels;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    uint32_t value;
    if (!absl::SimpleAtoi(line, &value)) {
      return absl::InvalidArgumentError(
          absl::StrCat(path, " line ", labels.size() + 1, ": '", line, "' is not a cluster id"));
    }
    labels.push_back(ClusterId(value));
  }
  if (labels.size() != expected) {
    return absl::InvalidArgumentError(
        absl::StrCat(path, " has ", labels.size(), " labels; the mesh has ", expected, " faces"));
  }
  return labels;
}

int RunEnergy(const Arguments& args) {
  if (args.positional().size() != 1 || !args.has("labels")) {
    return Fail(absl::InvalidArgumentError("energy: give INPUT and --labels FILE"));
  }
  absl::StatusOr<MeshEnergyOptions> options = EnergyFromArguments(args, "cvd");
  if (!options.ok()) return Fail(options.status());
  // The one set-up path (core/io/prepare_mesh.h): read, validate, adjacency, measures.
  absl::StatusOr<PreparedMesh> mesh = PrepareMeshFile(args.positional()[0]);
  if (!mesh.ok()) return Fail(mesh.status());
  absl::StatusOr<std::vector<ClusterId>> labels =
      ReadLabels(args.get("labels"), mesh->mesh.num_faces());
  if (!labels.ok()) return Fail(labels.status());
  // By definition: every face against its cluster's best proxy (not the sums' shortcut).
  const double energy = WithMeshEnergy(*options, mesh->mesh, mesh->measures, [&](const auto& e) {
    return EnergyFromProxies(e, *labels);
  });
  std::printf("%.17g\n", energy);
  return 0;
}

// GetStats of the one server `flags` names; a failure in plain words.
absl::StatusOr<v1::Stats> FetchStats(const ServerFlags& flags) {
  MLCLUST_ASSIGN_OR_RETURN(const std::shared_ptr<grpc::Channel> channel, ConnectTo(flags));
  auto stub = v1::Clustering::NewStub(channel);
  grpc::ClientContext context;
  context.set_deadline(
      absl::ToChronoTime(absl::Now() + std::min(flags.deadline, absl::Seconds(10))));
  v1::Stats stats;
  grpc::Status status = stub->GetStats(&context, v1::GetStatsRequest(), &stats);
  if (!status.ok()) {
    return PlainConnectionError(
        absl::Status(static_cast<absl::StatusCode>(status.error_code()), status.error_message()),
        flags.server);
  }
  return stats;
}

// Stats as text, one "name: value" line per field in the proto's order, every scalar
// included where it is zero (DebugString leaves out a proto3 scalar at its default, so a
// server with no failed job showed no jobs_failed line at all). Values as the text format
// writes them (strings quoted and escaped). A proto3 `optional` field is printed where it
// is set only: its absence says "not exposed" (the same fields as `--json` prints).
std::string StatsText(const v1::Stats& stats) {
  const google::protobuf::Descriptor* descriptor = v1::Stats::GetDescriptor();
  const google::protobuf::Reflection* reflection = v1::Stats::GetReflection();
  std::string text;
  for (int i = 0; i < descriptor->field_count(); ++i) {
    const google::protobuf::FieldDescriptor* field = descriptor->field(i);
    if (field->is_repeated()) continue;  // Stats has no repeated field
    const bool presence = field->cpp_type() == google::protobuf::FieldDescriptor::CPPTYPE_MESSAGE ||
                          field->containing_oneof() != nullptr;
    if (presence && !reflection->HasField(stats, field)) continue;
    std::string value;
    google::protobuf::TextFormat::PrintFieldValueToString(stats, field, -1, &value);
    absl::StrAppend(&text, field->name(), ": ", value, "\n");
  }
  return text;
}

// INVALID_ARGUMENT where `args` has positional arguments (`command` takes none).
absl::Status NoPositional(const Arguments& args, const std::string& command) {
  if (args.positional().empty()) return absl::OkStatus();
  return absl::InvalidArgumentError(
      absl::StrCat(command, ": unexpected argument '", args.positional()[0], "'"));
}

int RunStats(const Arguments& args) {
  if (absl::Status s = NoPositional(args, "stats"); !s.ok()) return Fail(s);
  if (!args.has("server")) return Fail(absl::InvalidArgumentError("stats: give --server ADDR"));
  const std::string address = args.get("server");
  if (absl::Status s = CheckServerAddress(address); !s.ok()) return Fail(s);
  absl::StatusOr<ServerFlags> flags = ServerFlagsFrom(args);
  if (!flags.ok()) return Fail(flags.status());
  const bool json = args.has("json");
  if (!client::NamesReplicas(address)) {
    absl::StatusOr<v1::Stats> stats = FetchStats(*flags);
    if (!stats.ok()) return Fail(stats.status());
    std::printf("%s", (json ? MessageJson(*stats) : StatsText(*stats)).c_str());
    return 0;
  }
  // Several replicas: each one's stats under its address; one that does not answer is
  // named (exit 1 when any did not).
  absl::StatusOr<std::vector<std::string>> replicas = client::ResolveReplicas(address);
  if (!replicas.ok()) return Fail(replicas.status());
  int code = 0;
  for (const std::string& replica : *replicas) {
    ServerFlags one = *flags;
    one.server = replica;
    json ? std::printf(R"({"replica": %s, "stats": )", JsonString(replica).c_str())
         : std::printf("== %s ==\n", replica.c_str());
    std::fflush(stdout);
    absl::StatusOr<v1::Stats> stats = FetchStats(one);
    if (!stats.ok()) {
      code = 1;
      if (json) std::printf("null}\n");
      std::fflush(stdout);
      Fail(stats.status());
      continue;
    }
    json ? std::printf("%s}\n", MessageJson(*stats).c_str())
         : std::printf("%s", StatsText(*stats).c_str());
  }
  return code;
}

// The text form of GetServerInfo's answer.
std::string InfoText(const v1::ServerInfo& info) {
  std::string out =
      absl::StrCat("mlclust ", info.version(), " (", info.build(), ")\n", "device: ",
                   info.gpu_available()
                       ? absl::StrCat(info.gl_renderer(),
                                      info.gl_is_software() ? " (software: auto uses the CPU)" : "")
                       : "cpu only (no GL context)",
                   "\nlimits: input ", info.max_input_bytes() >> 20, " MiB, queue ",
                   info.queue_capacity(), " jobs, clusters up to ", info.max_clusters(), "\n");
  for (const v1::AlgorithmDescription& algorithm : info.algorithms()) {
    std::vector<std::string> energies, stages;
    for (int e : algorithm.energies()) {
      const EnergyInfo* energy =
          FindEnergyByWire(algorithm.input_kind() == v1::INPUT_KIND_POINTS_F32 ? InputKind::kPoints
                                                                               : InputKind::kMesh,
                           e);
      energies.push_back(energy != nullptr ? energy->name : absl::StrCat(e));
    }
    for (const v1::StageDescription& stage : algorithm.stages()) {
      stages.push_back(absl::StrCat(stage.name(), stage.has_gpu() ? " (gpu|cpu)" : " (cpu)"));
    }
    absl::StrAppend(&out, "\n",
                    algorithm.input_kind() == v1::INPUT_KIND_POINTS_F32 ? "points" : "mesh", " ",
                    algorithm.name(), ": ", algorithm.title(), "\n  ", algorithm.help(),
                    "\n  energies: ", absl::StrJoin(energies, ", "),
                    "\n  stages: ", absl::StrJoin(stages, ", "), "\n");
    for (const v1::OptionDescription& option : algorithm.options()) {
      const std::string values =
          option.type() == "choice"
              ? absl::StrJoin(option.choices(), "|")
              : absl::StrCat(option.type(), " in [", option.low(), ", ", option.high(), "]");
      absl::StrAppend(&out, "  --", option.name(), " ", values, " (default ",
                      option.default_value(), ")\n");
    }
  }
  return out;
}

int RunInfo(const Arguments& args) {
  if (absl::Status s = NoPositional(args, "info"); !s.ok()) return Fail(s);
  std::unique_ptr<server::Server> embedded;
  std::shared_ptr<grpc::Channel> channel;
  const std::string address = args.get("server", "embedded");
  if (args.has("server")) {
    if (absl::Status s = CheckServerAddress(address); !s.ok()) return Fail(s);
    absl::StatusOr<ServerFlags> flags = ServerFlagsFrom(args);
    if (!flags.ok()) return Fail(flags.status());
    if (client::NamesReplicas(address)) {
      // Several replicas: the first that answers GetStats (replicas run the same build).
      absl::StatusOr<std::vector<std::string>> replicas = client::ResolveReplicas(address);
      if (!replicas.ok()) return Fail(replicas.status());
      client::ReplicaOptions probe;
      probe.connect = flags->connect;
      flags->server = client::OrderReplicas(*replicas, probe).front();
    }
    absl::StatusOr<std::shared_ptr<grpc::Channel>> connected = ConnectTo(*flags);
    if (!connected.ok()) return Fail(connected.status());
    channel = *connected;
  } else {
    server::ServerOptions options;
    options.log = false;
    absl::StatusOr<std::unique_ptr<server::Server>> started = server::Server::Start(options);
    if (!started.ok()) return Fail(started.status());
    embedded = *std::move(started);
    channel = embedded->InProcessChannel();
  }
  auto stub = v1::Clustering::NewStub(channel);
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
  v1::ServerInfo info;
  grpc::Status status = stub->GetServerInfo(&context, v1::GetServerInfoRequest(), &info);
  if (status.error_code() == grpc::StatusCode::UNIMPLEMENTED && embedded != nullptr) {
    // An embedded server without the handler: the same answer, built here.
    server::ServerFacts facts;
    facts.gl_renderer = embedded->gl_renderer();
    facts.gpu_available = !facts.gl_renderer.empty();
    facts.gl_is_software = absl::StrContains(facts.gl_renderer, "llvmpipe");
    facts.max_input_bytes = server::ServerOptions().max_input_bytes;
    facts.queue_capacity = static_cast<uint32_t>(server::ServerOptions().queue_capacity);
    info = server::MakeServerInfo(facts);
  } else if (!status.ok()) {
    return Fail(
        PlainConnectionError(absl::Status(static_cast<absl::StatusCode>(status.error_code()),
                                          absl::StrCat("GetServerInfo: ", status.error_message())),
                             address));
  }
  if (args.has("json")) {
    std::printf("%s", MessageJson(info).c_str());
  } else {
    std::printf("%s", InfoText(info).c_str());
  }
  return 0;
}

}  // namespace

Command EnergyCommand() {
  return {{"energy",
           "INPUT --labels FILE [--energy cvd] [energy options]",
           "Computes the energy of a labelling directly from the mesh file (a check): every face "
           "against its cluster's best proxy.",
           {{"",
             {{"labels", "FILE", "one cluster id per line, one line per face", 'o'},
              EnergyFlag(InputKind::kMesh, "cvd", /*wire_only=*/false)}},
            EnergyOptionGroup()}},
          RunEnergy};
}

Command StatsCommand() {
  return {ServerCommandLine("stats", "--server ADDR [--json]",
                            "Prints the server's queue depth, job counts and GL device.",
                            "the server, or several (each one's stats)",
                            {{"json", "", "print the stats as JSON"}}),
          RunStats};
}

Command InfoCommand() {
  return {ServerCommandLine("info", "[--server ADDR] [--json]",
                            "What the server is and runs (GetServerInfo): version, build, device "
                            "and renderer, every algorithm with its energies, options and stages, "
                            "and its limits. Without --server, the server this process would "
                            "embed.",
                            "the server (several: the first that answers)",
                            {{"json", "", "print the answer as JSON"}}),
          RunInfo};
}

}  // namespace mlclust::cli
