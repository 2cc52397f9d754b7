// mlclust: the command-line client. See `mlclust help`.
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>
#include <set>
#include <sstream>

#include "absl/status/statusor.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "absl/time/clock.h"
#include "client/client.h"
#include "client/job_commands.h"
#include "client/polygons.h"
#include "client/replicas.h"
#include "client/serve_command.h"
#include "core/base/status_macros.h"
#include "core/cluster/planar_merging.h"
#include "core/cluster/registry.h"
#include "core/coarsening/coarsening.h"
#include "core/energy/energies.h"
#include "core/io/draco_codec.h"
#include "core/io/mesh_io.h"
#include "core/io/points_io.h"
#include "core/io/prepare_mesh.h"
#include "core/mesh/face_measures.h"
#include "core/mesh/repair.h"
#include "google/protobuf/util/json_util.h"
#include "grpcpp/grpcpp.h"
#include "mlclust/v1/mlclust.grpc.pb.h"
#include "server/job_options.h"
#include "server/preview.h"
#include "server/server.h"
#ifdef MLCLUST_HAVE_PLOT
#include "client/plot.h"
#endif

namespace mlclust::cli {
namespace {

constexpr char kUsageTitle[] = R"(mlclust — multilevel clustering of meshes and point sets

usage:
)";

constexpr char kMeshUsage[] = R"(
  mlclust mesh INPUT [--server ADDR] [--algo ALGO] [--energy E] [--clusters K]
                     [--labels FILE] [--levels-csv FILE] [--ply FILE] [--coarse FILE]
                     [--preview FILE.png [--preview-size WxH] [--preview-view AZ,EL]]
                     [--device auto|gpu|cpu] [--quiet] [--json] [algorithm and energy options]
      Clusters the mesh INPUT (OBJ, PLY, OFF, STL, glTF/GLB, ... or a .drc sent as is) and
      receives every level. Without --server the server runs inside this process.
      --clusters K     the level written by --labels, --ply and --coarse (for single-level
                       algorithms the number of clusters to compute)
      --auto-k elbow   instead of --clusters, for hierarchies: the level at the first
                       elbow of the energy curve (section 4.4: the end of a near-zero
                       plateau, e.g. a cube's 6 sides with --energy planar); an error where
                       the curve has none
      --labels FILE    one line per input face: its cluster (0..K-1) at that level
      --levels-csv F   a row "clusters,energy" per level received
      --ply FILE       the mesh with one colour per cluster at that level
      --coarse FILE    the coarse mesh of that level: one vertex per cluster, a triangle
                       where three clusters meet (format by extension: .ply, .obj, .off)
      --coarse-placement centroid|qem   where coarse vertices go (default centroid)
                       A level that has no coarse mesh (small K: a cluster that is not a
                       disc, too few clusters around a handle) ends with exit code 3, after
                       the other outputs are written; the message names them and the
                       nearest K whose level coarsens.
      --planar-merge DEG  after a planar clustering (--energy planar, --algo vsa): merge
                       neighbouring clusters whose normals (eq. 3.37) differ by less than
                       DEG degrees, Delta_merging of section 3.3.2 (l. 1285, Fig. 3.17c:
                       1); the smallest angle first, normals recomputed after each merge
                       (ours: the text gives no order). --labels, --ply and --coarse get
                       the merged clusters.
      --repair         split non-manifold edges and vertices before sending (say what was
                       changed); face ids stay the input's
      --plot FILE.png  the energy of every level received against its clusters, elbows
                       (section 4.4) marked
      --per-polygon    OFF/OBJ input with quads or n-gons: a polygon's triangles stay in one
                       cluster and --labels writes one line per polygon. ml, hc, pml, emlo
                       and bb cluster whole polygons on the server (ours:
                       JobSpec.polygon_triangle_counts, on the CPU); other algorithms, or a
                       server that splits polygons (one older than that field), get a
                       post-pass: each polygon to the cluster of most of its area, the
                       energy recomputed
      --upload sequential|edgebreaker|auto  how the mesh travels (Draco). sequential
                       (default) keeps the face order by itself. edgebreaker carries a
                       per-face id attribute, by which the server puts the faces back in
                       the input's order (fandisk: 87,751 bytes lossless against 112,679;
                       25,933 with --quantize 14): labels map back exactly and HC's levels
                       are the same, but a face's corners may come back rotated and the
                       vertices renumbered, which changes the order EMLO, BB and ML visit
                       neighbours, so their results differ from a sequential upload's
                       (the same algorithm on a renumbered mesh: not the same labels).
                       auto: edgebreaker where the mesh passes the server's checks
                       (edgebreaker would drop degenerate faces and split non-manifold
                       vertices unseen), else sequential
      --quantize BITS  Draco position quantisation (0 = lossless float32, the default: the
                       server's energies are those of the input; 11-14 make uploads several
                       times smaller, at positions moved by up to 2^-BITS of the box)
      --preview FILE.png  a picture of that level (without --clusters: the last level;
                       the server's level, before --planar-merge), drawn by the server's GL
                       context: a three-quarter view, one colour per cluster, dark lines
                       between clusters
      --preview-size WxH  its size in pixels (default 1024x768; each side 16 to 4096)
      --preview-view AZ,EL  the camera in degrees (default 35,25: from the right of +z,
                       above; 215,25 looks from the other side)
      --levels K_HI:K_LO  hierarchies: only the levels with K_LO..K_HI clusters (a snapshot,
                       then deltas)
      --seed S         random seed (default 1)
      --device D       auto (default): the GPU for the stages that have a GPU
                       implementation where it is hardware; gpu: there even on a software
                       renderer; cpu: every stage on the CPU
)";

constexpr char kPointsUsage[] = R"(
  mlclust points INPUT [--dims D] [--server ADDR] [--algo ALGO] [--clusters K | --auto-k bic|elbow]
                       [--labels FILE] [--levels-csv FILE] [--seed S] [--levels K_HI:K_LO]
                       [--device auto|gpu|cpu] [--quiet] [--json] [algorithm options]
      Clusters the points of INPUT: .npy (float32/float64, m x d), .csv/.txt, or raw
      float32 (.f32/.bin/.raw, with --dims D). Hierarchies give every level from the
      voxel-grid start to one cluster; single-level algorithms one K.
      --auto-k bic writes the level with the highest BIC; --auto-k elbow the first elbow.
      --plot FILE.png  the energy of every level against its clusters, elbows marked
      --clusters K     single-level algorithms: K; bisecting: the top of its hierarchy;
                       xmeans: k_min, and --labels writes the K it found
)";

constexpr char kEnergyUsage[] = R"(
  mlclust energy INPUT --labels FILE [--energy cvd] [energy options]
      Computes the energy of a labelling directly from the mesh file (a check). Every mesh
      energy and energy option of `mlclust help mesh`.
)";

constexpr char kStatsUsage[] = R"(
  mlclust stats --server ADDR [--json]
      Prints the server's queue depth, job counts and GL device.
)";

constexpr char kInfoUsage[] = R"(
  mlclust info [--server ADDR] [--json]
      What the server is and runs (GetServerInfo): version, build, device and renderer,
      every algorithm with its energies, options and stages, and its limits. Without
      --server, the server this process would embed.

  mlclust --version | help [COMMAND] | COMMAND --help
      -k K is --clusters K, -o FILE is --labels FILE, -q is --quiet; --json prints the job
      summary of mesh and points as one JSON object.
)";

// "a|b|c", "INTEGER in [0, 1024]", "NUMBER in [0, 100]".
std::string OptionValueText(const OptionInfo& option) {
  switch (option.type) {
    case OptionInfo::Type::kChoice:
      return absl::StrJoin(option.choices, "|");
    case OptionInfo::Type::kInteger:
      return absl::StrCat("N in [", static_cast<int64_t>(option.low), ", ",
                          static_cast<int64_t>(option.high), "]");
    case OptionInfo::Type::kNumber:
      return absl::StrCat("X in [", option.low, ", ", option.high, "]");
  }
  return "";
}

// `text` in lines of at most 92 columns, each starting with `indent` spaces.
std::string Wrap(const std::string& text, size_t indent) {
  std::string out, line(indent, ' ');
  for (absl::string_view word : absl::StrSplit(text, ' ', absl::SkipEmpty())) {
    if (line.size() > indent && line.size() + 1 + word.size() > 92) {
      absl::StrAppend(&out, line, "\n");
      line.assign(indent, ' ');
    }
    absl::StrAppend(&line, line.size() > indent ? " " : "", word);
  }
  return absl::StrCat(out, line, "\n");
}

void AppendOption(std::string& out, const OptionInfo& option) {
  absl::StrAppend(&out, "        --", option.name, " ", OptionValueText(option), "\n",
                  Wrap(absl::StrCat(option.help, " (default ", option.default_text, ")"), 10));
}

// The algorithms, energies and options of `input`, from the registry.
std::string RegistryUsage(InputKind input) {
  std::string out =
      absl::StrCat("      --algo ALGO      (default ", DefaultAlgorithm(input).name, ")\n");
  for (const AlgorithmInfo& algorithm : Algorithms()) {
    if (algorithm.input != input) continue;
    absl::StrAppend(&out, "        ", algorithm.name, ": ", algorithm.title, "\n",
                    Wrap(absl::StrCat(algorithm.help,
                                      algorithm.divisive    ? " [hierarchy from K down to one]"
                                      : algorithm.hierarchy ? " [hierarchy]"
                                      : algorithm.chooses_k ? " [from K = k_min, finds its own K]"
                                                            : " [one K]"),
                         10));
  }
  if (input == InputKind::kMesh) {
    absl::StrAppend(&out, "      --energy E       (default: the algorithm's first below)\n");
    for (const EnergyInfo& energy : Energies()) {
      if (energy.input != input) continue;
      absl::StrAppend(&out, "        ", energy.name, ":\n", Wrap(energy.help, 10));
    }
  }
  for (const AlgorithmInfo& algorithm : Algorithms()) {
    if (algorithm.input != input) continue;
    absl::StrAppend(
        &out,
        Wrap(absl::StrCat(algorithm.name, " (energies: ", absl::StrJoin(algorithm.energies, ", "),
                          ")", algorithm.options.empty() ? ": no options of its own" : " options:"),
             4));
    for (const OptionInfo& option : algorithm.options) AppendOption(out, option);
  }
  if (input == InputKind::kMesh) {
    absl::StrAppend(&out, "    energy options (every mesh algorithm):\n");
    for (const OptionInfo& option : EnergyOptions()) AppendOption(out, option);
  }
  return out;
}

void PrintUsage(std::FILE* out) {
  std::fputs(kUsageTitle, out);
  std::fputs(ServeUsage(), out);
  std::fputs(kMeshUsage, out);
  std::fputs(RegistryUsage(InputKind::kMesh).c_str(), out);
  std::fputs(kPointsUsage, out);
  std::fputs(RegistryUsage(InputKind::kPoints).c_str(), out);
  std::fputs(kEnergyUsage, out);
  std::fputs(kStatsUsage, out);
  std::fputs(kInfoUsage, out);
  std::fputs(JobCommandsUsage(), out);
  std::fputs(ConnectionFlagsUsage(), out);
}

// The names of every registry option of `input` (each algorithm's own, and for meshes the
// energy options), once each.
std::vector<std::string> RegistryOptionNames(InputKind input) {
  std::vector<std::string> names;
  auto add = [&](const std::string& name) {
    if (std::find(names.begin(), names.end(), name) == names.end()) names.push_back(name);
  };
  for (const AlgorithmInfo& algorithm : Algorithms()) {
    if (algorithm.input != input) continue;
    for (const OptionInfo* option : AlgorithmOptions(algorithm)) add(option->name);
  }
  return names;
}

// --name value / --name=value options after the positional arguments; --quiet, --json and
// --help take no value; -k K is --clusters K, -o FILE is --labels FILE, -q is --quiet and
// -h is --help.
//
// A hand-written parser rather than CLI11 or absl flags: the option table (names, types,
// ranges, defaults, help) is the registry's, the server checks the values against it, and
// what is left to parse is "--name value" plus four short flags; absl flags are global
// (one set per process, not per subcommand) and CLI11 is one more dependency for that.
class Arguments {
 public:
  static absl::StatusOr<Arguments> Parse(int argc, char** argv, int first,
                                         const std::vector<std::string>& known) {
    static const std::map<std::string, std::string> kShort = {
        {"-k", "clusters"}, {"-o", "labels"}, {"-q", "quiet"}, {"-h", "help"}};
    static const std::set<std::string> kFlags = {"quiet",  "json",   "help",
                                                 "detach", "repair", "per-polygon"};
    Arguments args;
    for (int i = first; i < argc; ++i) {
      std::string arg = argv[i];
      std::string name, value;
      if (kShort.contains(arg)) {
        name = kShort.at(arg);
      } else if (absl::StartsWith(arg, "--")) {
        name = arg.substr(2);
      } else {
        args.positional_.push_back(arg);
        continue;
      }
      const size_t eq = name.find('=');
      const bool is_flag = kFlags.contains(name);
      if (eq != std::string::npos) {
        value = name.substr(eq + 1);
        name = name.substr(0, eq);
      } else if (!is_flag) {
        if (i + 1 >= argc) return absl::InvalidArgumentError(absl::StrCat(arg, " needs a value"));
        value = argv[++i];
      }
      if (name != "help" && std::find(known.begin(), known.end(), name) == known.end()) {
        return absl::InvalidArgumentError(absl::StrCat("unknown option --", name));
      }
      args.values_[name] = value;
    }
    return args;
  }

  bool has(const std::string& name) const { return values_.contains(name); }
  std::string get(const std::string& name, const std::string& fallback = "") const {
    auto it = values_.find(name);
    return it == values_.end() ? fallback : it->second;
  }
  // A non-negative integer up to `max` (a count that travels as uint32 on the wire is
  // refused above 2^32 - 1, never truncated).
  absl::StatusOr<uint64_t> GetUint(const std::string& name, uint64_t fallback,
                                   uint64_t max = UINT64_MAX) const {
    if (!has(name)) return fallback;
    uint64_t value;
    if (!absl::SimpleAtoi(get(name), &value)) {
      return absl::InvalidArgumentError(
          absl::StrCat("--", name, ": '", get(name), "' is not a non-negative integer"));
    }
    if (value > max) {
      return absl::InvalidArgumentError(
          absl::StrCat("--", name, ": ", value, " is over the largest accepted, ", max));
    }
    return value;
  }
  const std::vector<std::string>& positional() const { return positional_; }

 private:
  std::map<std::string, std::string> values_;
  std::vector<std::string> positional_;
};

int Fail(const absl::Status& status) {
  std::cerr << "mlclust: " << status.message() << "\n";
  return status.code() == absl::StatusCode::kInvalidArgument ? 2 : 1;
}

// --server ADDR: HOST:PORT (a name, IPv4 or [IPv6]) with a port in 1..65535, or a gRPC
// URI (unix:PATH, dns:///HOST:PORT, ...) passed as it is.
absl::Status CheckServerAddress(const std::string& address) {
  if (client::NamesReplicas(address)) {
    // Several replicas (client/replicas.h): each item is checked, a dns: name resolved.
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

// A failed call to the server at `address`, in plain words where gRPC's text is about
// the connection (the original text follows for the record).
absl::Status PlainConnectionError(const absl::Status& status, const std::string& address) {
  const std::string text(status.message());
  std::string plain;
  if (absl::StrContains(text, "Connection refused")) {
    plain = absl::StrCat("no server is listening at ", address,
                         " (connection refused): is `mlclust serve` running there, on this port?");
  } else if (absl::StrContains(text, "DNS resolution failed") ||
             absl::StrContains(text, "Domain name not found")) {
    plain = absl::StrCat("cannot find the host of ", address,
                         " (DNS: no such name): check the address, HOST:PORT");
  } else if (absl::StrContains(text, "Failed parsing HTTP/2") ||
             absl::StrContains(text, "Socket closed") ||
             absl::StrContains(text, "Connection reset") || absl::StrContains(text, "handshake") ||
             absl::StrContains(text, "SSL") || absl::StrContains(text, "ssl")) {
    plain = absl::StrCat("something answers at ", address,
                         ", but not an mlclust server speaking plain gRPC: a wrong port, or a "
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

// JSON string literal.
std::string JsonString(absl::string_view text) {
  std::string out = "\"";
  for (char c : text) {
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\t':
        out += "\\t";
        break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          out += absl::StrFormat("\\u%04x", static_cast<unsigned char>(c));
        } else {
          out += c;
        }
    }
  }
  return out + "\"";
}

std::string JsonNumber(double value) {
  return std::isfinite(value) ? absl::StrFormat("%.17g", value) : "null";
}

std::string JsonList(const google::protobuf::RepeatedField<uint32_t>& values) {
  return absl::StrCat("[", absl::StrJoin(values, ", "), "]");
}

// A message as JSON (proto3 JSON mapping, fields with default values included).
std::string MessageJson(const google::protobuf::Message& message) {
  std::string json;
  google::protobuf::util::JsonPrintOptions options;
  options.add_whitespace = true;
  options.always_print_primitive_fields = true;
  options.preserve_proto_field_names = true;
  (void)google::protobuf::util::MessageToJsonString(message, &json, options);
  return json;
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

// A one-line progress display on a terminal.
class ProgressLine {
 public:
  explicit ProgressLine(bool enabled) : enabled_(enabled && isatty(STDERR_FILENO)) {}
  void Update(const v1::JobEvent& event) {
    if (!enabled_) return;
    if (event.has_levels()) {
      levels_ += event.levels().cluster_count_size();
      clusters_ = event.levels().cluster_count(event.levels().cluster_count_size() - 1);
    } else if (event.has_snapshot()) {
      levels_ = 1;
      clusters_ = event.snapshot().cluster_count();
    } else if (event.has_progress()) {
      stage_ = event.progress().stage();
    } else if (event.has_accepted()) {
      stage_ = absl::StrCat("queued (", event.accepted().queue_position(), " ahead)");
    }
    const absl::Time now = absl::Now();
    if (now - last_ < absl::Milliseconds(100) && !event.final()) return;
    last_ = now;
    if (levels_ > 0) {
      std::fprintf(stderr, "\r\033[Kmlclust: %u levels received, %u clusters", levels_, clusters_);
    } else {
      std::fprintf(stderr, "\r\033[Kmlclust: %s", stage_.c_str());
    }
    if (event.final()) std::fputc('\n', stderr);
  }

 private:
  bool enabled_;
  uint32_t levels_ = 0, clusters_ = 0;
  std::string stage_;
  absl::Time last_ = absl::InfinitePast();
};

// --server and the connection flags (client/job_commands.h).
absl::StatusOr<ServerFlags> FlagsOf(const Arguments& args) {
  return ServerFlagsFrom([&](const std::string& name) -> std::optional<std::string> {
    if (!args.has(name)) return std::nullopt;
    return args.get(name);
  });
}

// --detach: the job is submitted and its id printed; watch it with `mlclust watch`.
int Detach(const Arguments& args, const v1::JobSpec& spec, const std::string& payload) {
  absl::StatusOr<ServerFlags> flags = FlagsOf(args);
  if (!flags.ok()) return Fail(flags.status());
  for (const char* output :
       {"labels", "levels-csv", "ply", "coarse", "json", "auto-k", "plot", "repair"}) {
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

// Runs `spec` on the server --server names, or on one started inside this process, with a
// progress line on a terminal.
// `labels_for_clusters`: the K of --clusters, whose level's labels the client rebuilds
// while the stream arrives (RunOptions::labels_for_clusters; LabelsOfLevel).
absl::StatusOr<client::JobResult> RunOnServer(const Arguments& args, const v1::JobSpec& spec,
                                              const std::string& payload, double* seconds,
                                              v1::Accepted* accepted = nullptr,
                                              uint32_t labels_for_clusters = 0) {
  std::unique_ptr<server::Server> embedded;
  std::shared_ptr<grpc::Channel> channel;
  MLCLUST_ASSIGN_OR_RETURN(const ServerFlags flags, FlagsOf(args));
  if (args.has("server")) {
    MLCLUST_RETURN_IF_ERROR(CheckServerAddress(args.get("server")));
    if (!client::NamesReplicas(args.get("server"))) {
      MLCLUST_ASSIGN_OR_RETURN(channel, ConnectTo(flags));
    }
  } else {
    server::ServerOptions options;
    options.log = false;
    absl::StatusOr<std::unique_ptr<server::Server>> started = server::Server::Start(options);
    if (!started.ok()) return started.status();
    embedded = *std::move(started);
    channel = embedded->InProcessChannel();
  }
  ProgressLine progress(!args.has("quiet"));
  client::RunOptions run_options;
  run_options.on_event = [&](const v1::JobEvent& event) {
    if (event.has_accepted() && accepted != nullptr) *accepted = event.accepted();
    progress.Update(event);
  };
  run_options.deadline = flags.deadline;
  run_options.labels_for_clusters = labels_for_clusters;
  const absl::Time started_at = absl::Now();
  if (args.has("server") && client::NamesReplicas(args.get("server"))) {
    // Several replicas: the least loaded first, the next where one did not accept the job.
    MLCLUST_ASSIGN_OR_RETURN(const std::vector<std::string> replicas,
                             client::ResolveReplicas(args.get("server")));
    client::ReplicaOptions replica_options;
    replica_options.connect = flags.connect;
    replica_options.in_order = flags.spread_in_order;
    replica_options.on_retry = [&](const std::string& replica, const absl::Status& status) {
      if (!args.has("quiet")) {
        std::cerr << "mlclust: replica " << replica << " did not accept the job ("
                  << status.message() << "); trying another\n";
      }
    };
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

// The level --clusters K writes: the last level with exactly K clusters (a single-level
// algorithm's result follows its start at the same K), else the first with fewer (PML
// may skip counts).
absl::StatusOr<size_t> ChooseLevel(const HierarchyLog& log, uint32_t k) {
  std::optional<size_t> level = log.LastLevelWith(k);
  if (!level.has_value()) level = log.FirstLevelWithAtMost(k);
  if (!level.has_value()) {
    return absl::NotFoundError(absl::StrCat("no level has ", k, " clusters or fewer (the last has ",
                                            log.cluster_count(log.num_levels() - 1), ")"));
  }
  return *level;
}

// The labels at `level`: those the client rebuilt as the stream arrived where it chose the
// same level (RunOptions::labels_for_clusters, taken from `result`), else replayed from
// level 0. The same labels either way.
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

// The job summary as one JSON object (--json): what ran, where, what came back, and the
// level written.
std::string SummaryJson(const Arguments& args, const std::string& input,
                        const std::string& element_name, size_t elements,
                        const AlgorithmInfo& algorithm, const v1::JobSpec& spec,
                        const HierarchyLog& log, double seconds, const v1::Done& done,
                        std::optional<size_t> level, const std::string& auto_k,
                        const std::set<std::string>& not_written = {}) {
  const EnergyInfo* energy = FindEnergyByWire(algorithm.input, spec.energy());
  const std::string energy_name = energy != nullptr ? energy->name : algorithm.energies[0];
  std::string json = absl::StrCat(
      "{\"input\": ", JsonString(input), ", \"", element_name, "\": ", elements,
      ", \"algorithm\": ", JsonString(algorithm.name), ", \"energy\": ", JsonString(energy_name),
      ", \"server\": ", JsonString(args.has("server") ? args.get("server") : "embedded"),
      ", \"device\": ", JsonString(done.device()),
      ", \"seconds\": ", absl::StrFormat("%.4f", seconds), ", \"levels\": ", log.num_levels(),
      ", \"triplets\": ", log.num_moves(), ", \"final_clusters\": ", done.final_clusters(),
      ", \"elbows\": ", JsonList(done.elbow_cluster_counts()));
  if (algorithm.input == InputKind::kPoints && algorithm.hierarchy) {
    absl::StrAppend(&json, ", \"bic_best_clusters\": ", done.bic_best_cluster_count(),
                    ", \"bic_first_decrease_clusters\": ", done.bic_first_decrease_cluster_count());
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
  for (const char* name : {"labels", "levels-csv", "ply", "coarse", "plot", "preview"}) {
    if (args.has(name) && !not_written.contains(name))
      outputs.push_back(absl::StrCat(JsonString(name), ": ", JsonString(args.get(name))));
  }
  absl::StrAppend(&json, ", \"outputs\": {", absl::StrJoin(outputs, ", "), "}}");
  return json;
}

// --levels K_HI:K_LO (either end may be empty): the levels with cluster counts in
// [K_LO, K_HI].
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
        "--levels: give K_HI:K_LO (cluster counts) with a hierarchy (--algo hc, ml, pml or "
        "bisecting)");
  }
  spec.set_levels_high(high);
  spec.set_levels_low(low);
  return absl::OkStatus();
}

// The wire energy from --energy (through the registry; not given: the algorithm's default).
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

// Every registry option of `input` given on the command line travels as text: the server
// checks it against the algorithm and names any that is unknown or out of range.
void SetOptions(const Arguments& args, InputKind input, v1::JobSpec& spec) {
  for (const std::string& name : RegistryOptionNames(input)) {
    if (args.has(name)) (*spec.mutable_options())[name] = args.get(name);
  }
}

absl::StatusOr<MeshEnergyOptions> EnergyFromArguments(const Arguments& args,
                                                      const std::string& default_name);

// Exit code of a mesh job whose other outputs were written but whose --coarse failed.
constexpr int kExitCoarseFailed = 3;

// --plot FILE.png: every level received (clusters, energy), the server's elbows marked.
absl::Status WritePlot(const std::string& path, const HierarchyLog& log, const v1::Done& done,
                       const std::string& title) {
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
  absl::Status status = client::WriteEnergyPlotPng(curve, options, path);
  if (!status.ok()) return absl::Status(status.code(), absl::StrCat("--plot: ", status.message()));
  return absl::OkStatus();
#else
  (void)log;
  (void)done;
  (void)title;
  return absl::UnimplementedError(absl::StrCat(
      "--plot ", path, ": this mlclust was built without cairo (libcairo2-dev); no plot"));
#endif
}

// The outputs given on the command line, as "--labels L.txt, --ply P.ply" (those in `names`).
std::string OutputList(const Arguments& args, std::initializer_list<const char*> names) {
  std::vector<std::string> given;
  for (const char* name : names) {
    if (args.has(name)) given.push_back(absl::StrCat("--", name, " ", args.get(name)));
  }
  return given.empty() ? "none" : absl::StrJoin(given, ", ");
}

// The level nearest to `level` (by cluster count; the larger count on a tie) whose labels
// coarsen, among the levels of other counts, trying at most `max_tries`; nullopt if none.
std::optional<uint32_t> NearestCoarsening(const HierarchyLog& log, size_t level,
                                          const TriangleMesh& mesh, const FaceAdjacency& adjacency,
                                          const CoarseningOptions& options, int max_tries) {
  const int64_t k = log.cluster_count(level);
  std::map<uint32_t, size_t> last_with;  // count -> the last level with it
  for (size_t l = 0; l < log.num_levels(); ++l) last_with[log.cluster_count(l)] = l;
  std::vector<std::pair<uint32_t, size_t>> candidates(last_with.begin(), last_with.end());
  std::sort(candidates.begin(), candidates.end(), [k](const auto& a, const auto& b) {
    const int64_t da = std::abs(static_cast<int64_t>(a.first) - k);
    const int64_t db = std::abs(static_cast<int64_t>(b.first) - k);
    return da != db ? da < db : a.first > b.first;
  });
  int tries = 0;
  for (const auto& [count, candidate] : candidates) {
    if (count == k) continue;
    if (++tries > max_tries) break;
    absl::StatusOr<std::vector<ClusterId>> labels = log.LabelsAt(candidate);
    if (labels.ok() && CoarsenMesh(mesh, adjacency, *labels, options).ok()) return count;
  }
  return std::nullopt;
}

// --preview FILE.png [--preview-size WxH]: the server draws the level --clusters K chooses
// (the last level without K) and sends it as a Preview event.
absl::Status SetPreview(const Arguments& args, uint32_t clusters, v1::JobSpec& spec) {
  if (!args.has("preview")) {
    for (const char* name : {"preview-size", "preview-view"}) {
      if (args.has(name)) {
        return absl::InvalidArgumentError(absl::StrCat("--", name, " needs --preview FILE.png"));
      }
    }
    return absl::OkStatus();
  }
  if (args.get("preview").empty()) return absl::InvalidArgumentError("--preview: no file name");
  v1::PreviewRequest* preview = spec.mutable_preview();
  preview->set_cluster_count(clusters);
  if (args.has("preview-size")) {
    MLCLUST_ASSIGN_OR_RETURN(const auto size,
                             server::ParsePreviewSize(args.get("preview-size"), "--preview-size"));
    preview->set_width(size.first);
    preview->set_height(size.second);
  }
  if (args.has("preview-view")) {
    MLCLUST_ASSIGN_OR_RETURN(const auto view,
                             server::ParsePreviewView(args.get("preview-view"), "--preview-view"));
    preview->set_azimuth_degrees(view.first);
    preview->set_elevation_degrees(view.second);
  }
  return absl::OkStatus();
}

absl::Status WritePreview(const std::string& path, const v1::Preview& preview) {
  if (preview.png().empty()) {
    return absl::DataLossError("--preview: the server sent no preview");
  }
  std::ofstream out(path, std::ios::binary);
  out.write(preview.png().data(), static_cast<std::streamsize>(preview.png().size()));
  out.close();
  if (!out) return absl::UnavailableError(absl::StrCat("--preview: cannot write ", path));
  return absl::OkStatus();
}

int Mesh(const Arguments& args) {
  if (args.positional().size() != 1) {
    return Fail(absl::InvalidArgumentError("mesh: give exactly one INPUT file"));
  }
  const std::string& input_path = args.positional()[0];
  absl::StatusOr<uint64_t> clusters = args.GetUint("clusters", 0, UINT32_MAX);
  if (!clusters.ok()) return Fail(clusters.status());
  // --auto-k elbow: the level K is the first elbow of the energy curve (section 4.4).
  const std::string auto_k = args.get("auto-k", "");
  if (!auto_k.empty() && auto_k != "elbow") {
    return Fail(absl::InvalidArgumentError(
        "--auto-k for meshes must be elbow (section 4.4; the BIC is for points)"));
  }
  if (!auto_k.empty() && *clusters > 0) {
    return Fail(absl::InvalidArgumentError("give --clusters K or --auto-k elbow, not both"));
  }
  if (!auto_k.empty() && args.has("preview")) {
    return Fail(absl::InvalidArgumentError(
        "--preview needs --clusters K: the server draws the level before --auto-k chooses it"));
  }
  if ((args.has("labels") || args.has("ply")) && *clusters == 0 && auto_k.empty()) {
    return Fail(absl::InvalidArgumentError(
        "--labels and --ply need --clusters K (K >= 1) or --auto-k elbow"));
  }
  v1::JobSpec spec;
  spec.set_input_kind(v1::INPUT_KIND_DRACO_MESH);
  absl::StatusOr<const AlgorithmInfo*> algorithm = GetAlgorithm(args, InputKind::kMesh);
  if (!algorithm.ok()) return Fail(algorithm.status());
  const std::string algo = (*algorithm)->name;
  const bool hierarchy = (*algorithm)->hierarchy;
  spec.set_algorithm(static_cast<v1::Algorithm>((*algorithm)->wire));
  if (absl::Status status = SetEnergy(args, InputKind::kMesh, spec); !status.ok()) {
    return Fail(status);
  }
  if (!hierarchy && *clusters == 0) {
    return Fail(absl::InvalidArgumentError(absl::StrCat("--clusters: ", algo, " needs K >= 1")));
  }
  if (!auto_k.empty() && !hierarchy) {
    return Fail(absl::InvalidArgumentError(
        absl::StrCat("--auto-k needs a hierarchy (--algo ml, pml or hc), not ", algo)));
  }
  if (!hierarchy) spec.set_clusters(static_cast<uint32_t>(*clusters));
  if (absl::Status status = SetLevels(args, hierarchy, spec); !status.ok()) return Fail(status);
  absl::StatusOr<uint64_t> seed = args.GetUint("seed", 1);
  if (!seed.ok()) return Fail(seed.status());
  spec.set_seed(*seed);
  SetOptions(args, InputKind::kMesh, spec);
  const std::string placement = args.get("coarse-placement", "centroid");
  if (placement != "centroid" && placement != "qem") {
    return Fail(absl::InvalidArgumentError("--coarse-placement must be centroid or qem"));
  }
  if (args.has("coarse") && *clusters == 0 && auto_k.empty()) {
    return Fail(absl::InvalidArgumentError("--coarse needs --clusters K (K >= 1) or --auto-k"));
  }
  // --planar-merge DEG: a post-pass over the level written, for a planar clustering.
  double planar_merge_degrees = -1;
  if (args.has("planar-merge")) {
    if (!absl::SimpleAtod(args.get("planar-merge"), &planar_merge_degrees) ||
        !(planar_merge_degrees >= 0 && planar_merge_degrees <= 180)) {
      return Fail(absl::InvalidArgumentError(absl::StrCat(
          "--planar-merge: '", args.get("planar-merge"), "' is not an angle in [0, 180] degrees")));
    }
    const EnergyInfo* energy = FindEnergyByWire(InputKind::kMesh, spec.energy());
    const std::string energy_name = energy != nullptr ? energy->name : (*algorithm)->energies[0];
    if (energy_name != "planar") {
      return Fail(absl::InvalidArgumentError(
          absl::StrCat("--planar-merge merges the clusters of a planar clustering (--energy "
                       "planar, or --algo vsa); this job's energy is ",
                       energy_name)));
    }
    if (*clusters == 0) {
      return Fail(absl::InvalidArgumentError("--planar-merge needs --clusters K (K >= 1)"));
    }
  }
  if (args.has("per-polygon") && *clusters == 0) {
    return Fail(absl::InvalidArgumentError("--per-polygon needs --clusters K (K >= 1)"));
  }
  const std::string upload = args.get("upload", "sequential");
  if (upload != "auto" && upload != "sequential" && upload != "edgebreaker") {
    return Fail(absl::InvalidArgumentError("--upload must be auto, sequential or edgebreaker"));
  }
  absl::StatusOr<uint64_t> quantize = args.GetUint("quantize", 0, 30);
  if (!quantize.ok()) return Fail(quantize.status());
  spec.set_device(args.get("device", "auto"));
  spec.set_label(input_path);
  if (absl::Status status = SetPreview(args, static_cast<uint32_t>(*clusters), spec);
      !status.ok()) {
    return Fail(status);
  }

  // The mesh is read locally (its faces are the ids of every output) and sent compressed;
  // a .drc file is sent as it is.
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(input_path);
  if (!mesh.ok()) return Fail(mesh.status());
  if (*clusters > mesh->num_faces()) {
    return Fail(absl::InvalidArgumentError(absl::StrCat(
        "--clusters: ", *clusters, " is more than the mesh's ", mesh->num_faces(), " faces")));
  }
  std::vector<uint32_t> polygon_triangles;  // --per-polygon: triangles of each polygon
  bool polygons_sent = false;               // --per-polygon: the server clusters whole polygons
  if (args.has("per-polygon")) {
    absl::StatusOr<std::vector<uint32_t>> counts = client::ReadPolygonTriangleCounts(input_path);
    if (!counts.ok()) return Fail(counts.status());
    polygon_triangles = *std::move(counts);
    polygons_sent = client::ServerClustersPolygons((*algorithm)->name);
    if (polygons_sent) {
      for (uint32_t count : polygon_triangles) spec.add_polygon_triangle_counts(count);
    }
  }
  // --repair: the mesh sent (and coarsened) has its non-manifold edges and vertices split;
  // faces keep their ids, so labels, --ply (the input's vertices) and --plot are unchanged.
  std::optional<TriangleMesh> repaired;
  if (args.has("repair")) {
    absl::StatusOr<MeshRepairResult> repair = RepairNonManifold(*mesh);
    if (!repair.ok()) {
      return Fail(absl::Status(repair.status().code(),
                               absl::StrCat("--repair: ", repair.status().message())));
    }
    std::fprintf(stderr, "mlclust: --repair: %s\n", repair->report.Summary().c_str());
    if (repair->report.changed()) repaired = std::move(repair->mesh);
  }
  const TriangleMesh& sent = repaired.has_value() ? *repaired : *mesh;
  // The upload: a .drc file as it is (unless repaired); otherwise Draco: sequential (the
  // default: the server sees the mesh exactly as read), or edgebreaker with the per-face id
  // attribute (--upload edgebreaker; auto: where the mesh passes the server's checks, so
  // that sequential lets the server name what is wrong).
  std::string upload_method = "file";
  absl::StatusOr<std::string> payload;
  if (absl::EndsWithIgnoreCase(input_path, ".drc") && !repaired.has_value()) {
    payload = ReadFileBytes(input_path);
  } else {
    DracoEncodeOptions encode;
    encode.position_quantization_bits = static_cast<int>(*quantize);
    const bool edgebreaker =
        upload == "edgebreaker" || (upload == "auto" && ValidateMesh(sent).ok());
    if (edgebreaker) {
      encode.method = DracoMethod::kEdgebreaker;
      encode.write_face_ids = true;
    }
    upload_method = edgebreaker ? "edgebreaker+face-ids" : "sequential";
    payload = EncodeMeshToDraco(sent, encode);
  }
  if (!payload.ok()) return Fail(payload.status());
  if (args.has("detach")) return Detach(args, spec, *payload);

  double seconds = 0;
  v1::Accepted accepted;
  absl::StatusOr<client::JobResult> result =
      RunOnServer(args, spec, *payload, &seconds, &accepted,
                  auto_k.empty() ? static_cast<uint32_t>(*clusters) : 0);
  if (!result.ok()) return Fail(result.status());
  const HierarchyLog& log = result->hierarchy;
  if (log.num_elements() != mesh->num_faces()) {
    return Fail(absl::DataLossError(absl::StrCat("the server sent labels for ", log.num_elements(),
                                                 " faces; the mesh has ", mesh->num_faces())));
  }

  if (args.has("levels-csv")) {
    if (absl::Status s = WriteLevelsCsv(args.get("levels-csv"), log); !s.ok()) return Fail(s);
  }
  const EnergyInfo* job_energy = FindEnergyByWire(InputKind::kMesh, spec.energy());
  const std::string energy_name =
      job_energy != nullptr ? job_energy->name : (*algorithm)->energies[0];
  if (args.has("plot")) {
    if (absl::Status s =
            WritePlot(args.get("plot"), log, result->done,
                      absl::StrCat(input_path, ": ", algo, ", ", energy_name, " energy"));
        !s.ok()) {
      return Fail(s);
    }
  }
  std::string elbow_note;
  if (auto_k == "elbow") {
    if (result->done.elbow_cluster_counts().empty()) {
      return Fail(absl::NotFoundError(
          "--auto-k elbow: the energy curve has no elbow by section 4.4's definition (the "
          "energy stays near zero up to the true number of shapes, then jumps); this one "
          "rises steadily, as when the energy does not fit the model's shapes exactly: choose "
          "--clusters K (--plot FILE.png shows the curve)"));
    }
    clusters = result->done.elbow_cluster_counts(0);
    elbow_note = absl::StrCat("; --auto-k: the first elbow, ", *clusters, " clusters");
  }
  std::string level_note;
  std::optional<size_t> chosen_level;
  std::string coarse_error;
  std::optional<uint32_t> coarse_nearest;
  std::string post_pass_json;  // --planar-merge and --per-polygon in the JSON summary
  if (*clusters > 0) {
    absl::StatusOr<size_t> level = ChooseLevel(log, static_cast<uint32_t>(*clusters));
    if (!level.ok()) return Fail(level.status());
    absl::StatusOr<std::vector<ClusterId>> labels = LabelsOfLevel(*result, *level);
    if (!labels.ok()) return Fail(labels.status());
    std::vector<uint32_t> compact = client::CompactLabels(*labels);
    std::string merge_note;
    if (planar_merge_degrees >= 0) {
      std::vector<ClusterId> level_ids(compact.begin(), compact.end());
      PlanarMergingOptions merging;
      merging.max_angle_degrees = planar_merge_degrees;
      absl::StatusOr<PlanarMergingResult> merged = MergePlanarClusters(sent, level_ids, merging);
      if (!merged.ok()) {
        return Fail(absl::Status(merged.status().code(),
                                 absl::StrCat("--planar-merge: ", merged.status().message())));
      }
      compact = client::CompactLabels(merged->labels);
      merge_note =
          absl::StrFormat("; planar merge (Delta_merging %g deg): %u -> %u clusters",
                          planar_merge_degrees, merged->input_clusters, merged->output_clusters);
      absl::StrAppend(&post_pass_json, R"(, "planar_merge": {"degrees": )",
                      JsonNumber(planar_merge_degrees),
                      ", \"clusters_before\": ", merged->input_clusters,
                      ", \"clusters_after\": ", merged->output_clusters, "}");
    }
    std::vector<uint32_t> written = compact;  // what --labels writes
    if (args.has("per-polygon")) {
      std::vector<ClusterId> face_ids(compact.begin(), compact.end());
      absl::StatusOr<client::PolygonLabels> polygons =
          client::LabelsPerPolygon(*mesh, polygon_triangles, face_ids);
      if (!polygons.ok()) return Fail(polygons.status());
      compact = client::CompactLabels(polygons->per_face);
      written.clear();
      size_t first = 0;
      for (uint32_t count : polygon_triangles) {
        written.push_back(compact[first]);
        first += count;
      }
      // The energy of the labels written, from its definition (as `mlclust energy`).
      absl::StatusOr<MeshEnergyOptions> energy_options = EnergyFromArguments(args, energy_name);
      if (!energy_options.ok()) return Fail(energy_options.status());
      absl::StatusOr<PreparedMesh> prepared = PrepareMesh(sent);
      if (!prepared.ok()) return Fail(prepared.status());
      std::vector<ClusterId> labels_now(compact.begin(), compact.end());
      const double energy =
          WithMeshEnergy(*energy_options, prepared->mesh, prepared->measures,
                         [&](const auto& e) { return EnergyFromProxies(e, labels_now); });
      // No polygon split: the server clustered whole polygons; otherwise this was the
      // post-pass (an algorithm the server runs per triangle only, or an older server).
      const bool in_algorithms = polygons_sent && polygons->split_polygons == 0;
      if (polygons_sent && !in_algorithms) {
        std::fprintf(stderr,
                     "mlclust: --per-polygon: the server split %u polygons (it predates "
                     "JobSpec.polygon_triangle_counts); each went to the cluster of most of "
                     "its area instead\n",
                     polygons->split_polygons);
      }
      absl::StrAppend(&post_pass_json, R"(, "per_polygon": {"polygons": )",
                      polygon_triangles.size(),
                      ", \"in_algorithms\": ", in_algorithms ? "true" : "false",
                      ", \"split_polygons\": ", polygons->split_polygons,
                      ", \"clusters\": ", *std::max_element(compact.begin(), compact.end()) + 1,
                      ", \"energy\": ", JsonNumber(energy), "}");
      const uint32_t polygon_clusters = *std::max_element(compact.begin(), compact.end()) + 1;
      merge_note = absl::StrCat(
          merge_note,
          in_algorithms
              ? absl::StrFormat("; per polygon: %zu polygons, each one element of the "
                                "clustering (none split): %u clusters, energy %.10g",
                                polygon_triangles.size(), polygon_clusters, energy)
              : absl::StrFormat("; per polygon: %zu polygons, %u were split and went to the "
                                "cluster of most of their area: %u clusters, energy %.10g",
                                polygon_triangles.size(), polygons->split_polygons,
                                polygon_clusters, energy));
    }
    if (args.has("labels")) {
      if (absl::Status s = WriteLabels(args.get("labels"), written); !s.ok()) return Fail(s);
    }
    std::vector<ClusterId> ids(compact.size());
    for (size_t i = 0; i < compact.size(); ++i) ids[i] = ClusterId(compact[i]);
    if (args.has("ply")) {
      if (absl::Status s = WriteClusteredPly(args.get("ply"), *mesh, ids); !s.ok()) {
        return Fail(s);
      }
    }
    if (args.has("coarse")) {
      CoarseningOptions options;
      options.placement = placement == "qem" ? CoarseningOptions::Placement::kQuadric
                                             : CoarseningOptions::Placement::kCentroid;
      absl::StatusOr<FaceAdjacency> adjacency = BuildFaceAdjacency(sent);
      if (!adjacency.ok()) return Fail(adjacency.status());
      absl::StatusOr<TriangleMesh> coarse = CoarsenMesh(sent, *adjacency, ids, options);
      if (coarse.status().code() == absl::StatusCode::kFailedPrecondition) {
        // This level has no coarse mesh (small K): the other outputs stand; say which, and
        // the nearest level that coarsens (among the levels received, without a merge).
        coarse_error = std::string(coarse.status().message());
        if (planar_merge_degrees < 0) {
          coarse_nearest = NearestCoarsening(log, *level, sent, *adjacency, options, 32);
        }
      } else if (!coarse.ok()) {
        return Fail(coarse.status());
      } else if (absl::Status s = WriteMeshFile(args.get("coarse"), *coarse); !s.ok()) {
        return Fail(s);
      }
    }
    level_note = absl::StrFormat("%s; level %zu: %u clusters, energy %.10g%s", elbow_note, *level,
                                 log.cluster_count(*level), log.energy(*level), merge_note);
    chosen_level = *level;
  }
  std::string preview_note;
  if (args.has("preview")) {
    const v1::Preview& preview = result->preview;
    if (absl::Status s = WritePreview(args.get("preview"), preview); !s.ok()) return Fail(s);
    preview_note = absl::StrFormat("; preview %ux%u of %u clusters in %.3f s: %s", preview.width(),
                                   preview.height(), preview.cluster_count(),
                                   result->done.seconds_preview(), args.get("preview"));
  }
  if (args.has("json")) {
    std::string json = SummaryJson(
        args, input_path, "faces", mesh->num_faces(), **algorithm, spec, log, seconds, result->done,
        chosen_level, auto_k,
        coarse_error.empty() ? std::set<std::string>{} : std::set<std::string>{"coarse"});
    // The upload, and --coarse's failure (its file is then not among the outputs).
    json.pop_back();
    absl::StrAppend(&json, R"(, "upload": {"method": )", JsonString(upload_method),
                    ", \"bytes\": ", payload->size(), ", \"quantization_bits\": ", *quantize,
                    ", \"face_ids\": ", accepted.face_ids() ? "true" : "false",
                    ", \"face_order\": ", JsonString(accepted.face_order()), "}");
    absl::StrAppend(&json, post_pass_json);
    if (!coarse_error.empty()) {
      absl::StrAppend(&json, ", \"coarse_error\": ", JsonString(coarse_error),
                      ", \"coarse_nearest_clusters\": ",
                      coarse_nearest.has_value() ? absl::StrCat(*coarse_nearest) : "null");
    }
    std::printf("%s}\n", json.c_str());
  } else {
    std::printf("%s: %zu faces, %zu levels, %zu triplets in %.3f s on %s (%s)%s%s%s\n",
                input_path.c_str(), mesh->num_faces(), log.num_levels(), log.num_moves(), seconds,
                result->done.device().c_str(), args.has("server") ? "remote" : "embedded",
                level_note.c_str(), ElbowNote(result->done).c_str(), preview_note.c_str());
  }
  if (!coarse_error.empty()) {
    std::fprintf(stderr,
                 "mlclust: --coarse %s: not written: this level has no coarse mesh: %s\n"
                 "  written: %s\n  %s\n",
                 args.get("coarse").c_str(), coarse_error.c_str(),
                 OutputList(args, {"labels", "levels-csv", "ply", "plot", "preview"}).c_str(),
                 coarse_nearest.has_value()
                     ? absl::StrCat("the nearest level that coarsens has ", *coarse_nearest,
                                    " clusters: --clusters ", *coarse_nearest)
                           .c_str()
                     : (hierarchy ? "no level near it coarsens (32 tried): try a larger --clusters"
                                  : "try a larger --clusters"));
    return kExitCoarseFailed;
  }
  return 0;
}

int Points(const Arguments& args) {
  if (args.positional().size() != 1) {
    return Fail(absl::InvalidArgumentError("points: give exactly one INPUT file"));
  }
  const std::string& input_path = args.positional()[0];
  absl::StatusOr<uint64_t> clusters = args.GetUint("clusters", 0, UINT32_MAX);
  absl::StatusOr<uint64_t> dims = args.GetUint("dims", 0);
  absl::StatusOr<uint64_t> seed = args.GetUint("seed", 1);
  for (const auto* value : {&clusters, &dims, &seed}) {
    if (!value->ok()) return Fail(value->status());
  }
  absl::StatusOr<const AlgorithmInfo*> algorithm = GetAlgorithm(args, InputKind::kPoints);
  if (!algorithm.ok()) return Fail(algorithm.status());
  const std::string algo = (*algorithm)->name;
  const bool hierarchy = (*algorithm)->hierarchy;
  const std::string auto_k = args.get("auto-k", "");
  if (!auto_k.empty() && auto_k != "bic" && auto_k != "elbow") {
    return Fail(absl::InvalidArgumentError("--auto-k must be bic or elbow"));
  }
  if (!auto_k.empty() && !hierarchy) {
    return Fail(
        absl::InvalidArgumentError("--auto-k needs a hierarchy: --algo ml, pml, hc or bisecting"));
  }
  // Bisecting k-means: a hierarchy whose top, K, is --clusters. X-means: --clusters is k_min
  // and the result (the last level) has the K it found.
  const bool divisive = (*algorithm)->divisive;
  const bool chooses_k = (*algorithm)->chooses_k;
  // LN k-means from the voxel grid: one cluster per occupied cell, no K.
  const bool grid_start = algo == "lnkmeans" && args.get("init", "") == "grid";
  if (grid_start && *clusters != 0) {
    return Fail(absl::InvalidArgumentError(
        "--clusters: --init grid starts from one cluster per occupied voxel (--grid A)"));
  }
  if ((!hierarchy || divisive) && !grid_start && *clusters == 0) {
    return Fail(absl::InvalidArgumentError(
        absl::StrCat("--clusters: ", algo, " needs K >= 1", chooses_k ? " (k_min)" : "")));
  }
  if (args.has("labels") && *clusters == 0 && auto_k.empty() && !grid_start) {
    return Fail(absl::InvalidArgumentError("--labels needs --clusters K or --auto-k"));
  }
  if (*dims > 4096) return Fail(absl::InvalidArgumentError("--dims: over 4096"));

  PointReadOptions read;
  read.dims = static_cast<uint32_t>(*dims);
  absl::StatusOr<PointSet> points = ReadPointsFile(input_path, read);
  if (!points.ok()) return Fail(points.status());
  if (*clusters > points->num_points()) {
    return Fail(absl::InvalidArgumentError(absl::StrCat(
        "--clusters: ", *clusters, " is more than the ", points->num_points(), " points")));
  }

  v1::JobSpec spec;
  spec.set_input_kind(v1::INPUT_KIND_POINTS_F32);
  spec.set_point_dims(points->dims);
  spec.set_algorithm(static_cast<v1::Algorithm>((*algorithm)->wire));
  spec.set_energy(v1::ENERGY_VARIANCE);
  spec.set_label(input_path);
  spec.set_seed(*seed);
  spec.set_device(args.get("device", "auto"));
  if (!hierarchy || divisive) spec.set_clusters(static_cast<uint32_t>(*clusters));
  if (absl::Status status = SetLevels(args, hierarchy, spec); !status.ok()) return Fail(status);
  SetOptions(args, InputKind::kPoints, spec);
  const std::string payload(reinterpret_cast<const char*>(points->values.data()),
                            points->values.size() * sizeof(float));
  if (args.has("detach")) return Detach(args, spec, payload);
  double seconds = 0;
  absl::StatusOr<client::JobResult> result = RunOnServer(
      args, spec, payload, &seconds, nullptr,
      auto_k.empty() && !grid_start && !chooses_k ? static_cast<uint32_t>(*clusters) : 0);
  if (!result.ok()) return Fail(result.status());
  const HierarchyLog& log = result->hierarchy;
  if (log.num_elements() != points->num_points()) {
    return Fail(absl::DataLossError(absl::StrCat("the server sent labels for ", log.num_elements(),
                                                 " points; the input has ", points->num_points())));
  }
  if (args.has("levels-csv")) {
    if (absl::Status s = WriteLevelsCsv(args.get("levels-csv"), log); !s.ok()) return Fail(s);
  }
  if (args.has("plot")) {
    if (absl::Status s = WritePlot(args.get("plot"), log, result->done,
                                   absl::StrCat(input_path, ": ", algo, ", variance"));
        !s.ok()) {
      return Fail(s);
    }
  }
  // The level to write: --clusters K, or the one --auto-k chooses.
  std::optional<size_t> level;
  std::string chosen;
  if (auto_k == "elbow") {
    if (result->done.elbow_cluster_counts().empty()) {
      return Fail(absl::NotFoundError(
          "--auto-k elbow: the energy curve has no jump (ours for points; try --auto-k bic)"));
    }
    const uint32_t k = result->done.elbow_cluster_counts(0);
    level = log.LastLevelWith(k);
    chosen = absl::StrCat("; elbow at ", k, " clusters");
  } else if (auto_k == "bic") {
    // The server scores every level of the hierarchy (Done's BIC fields).
    const uint32_t k = result->done.bic_best_cluster_count();
    if (k == 0) return Fail(absl::NotFoundError("--auto-k bic: the server sent no BIC"));
    level = log.LastLevelWith(k);
    if (!level.has_value()) {
      return Fail(
          absl::NotFoundError(absl::StrCat("--auto-k bic: the BIC is highest at ", k,
                                           " clusters, a level outside the range that was sent")));
    }
    chosen = absl::StrCat("; BIC highest at ", k, " clusters, first decrease after ",
                          result->done.bic_first_decrease_cluster_count());
  } else if (grid_start || chooses_k) {
    level = log.num_levels() - 1;
  } else if (*clusters > 0) {
    absl::StatusOr<size_t> by_k = ChooseLevel(log, static_cast<uint32_t>(*clusters));
    if (!by_k.ok()) return Fail(by_k.status());
    level = *by_k;
  }
  std::string level_note;
  if (level.has_value()) {
    absl::StatusOr<std::vector<ClusterId>> labels = LabelsOfLevel(*result, *level);
    if (!labels.ok()) return Fail(labels.status());
    if (args.has("labels")) {
      if (absl::Status s = WriteLabels(args.get("labels"), client::CompactLabels(*labels));
          !s.ok()) {
        return Fail(s);
      }
    }
    level_note = absl::StrFormat("; level %zu: %u clusters, energy %.10g", *level,
                                 log.cluster_count(*level), log.energy(*level));
  }
  if (args.has("json")) {
    std::printf("%s\n", SummaryJson(args, input_path, "points", points->num_points(), **algorithm,
                                    spec, log, seconds, result->done, level, auto_k)
                            .c_str());
    return 0;
  }
  std::printf("%s: %zu points in %u dimensions, %zu levels, %zu triplets in %.3f s (%s)%s%s%s\n",
              input_path.c_str(), points->num_points(), points->dims, log.num_levels(),
              log.num_moves(), seconds, args.has("server") ? "remote" : "embedded",
              level_note.c_str(), chosen.c_str(), ElbowNote(result->done).c_str());
  return 0;
}

// --energy (default cvd; every mesh energy, also those not on the wire) and its options.
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

int Energy(const Arguments& args) {
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

int Stats(const Arguments& args) {
  if (!args.has("server")) return Fail(absl::InvalidArgumentError("stats: give --server ADDR"));
  const std::string address = args.get("server");
  if (absl::Status s = CheckServerAddress(address); !s.ok()) return Fail(s);
  absl::StatusOr<ServerFlags> flags = FlagsOf(args);
  if (!flags.ok()) return Fail(flags.status());
  if (client::NamesReplicas(address)) {
    // Several replicas: each one's stats under its address; one that does not answer is
    // named (exit 1 when any did not).
    absl::StatusOr<std::vector<std::string>> replicas = client::ResolveReplicas(address);
    if (!replicas.ok()) return Fail(replicas.status());
    int code = 0;
    for (const std::string& replica : *replicas) {
      ServerFlags one = *flags;
      one.server = replica;
      args.has("json") ? std::printf(R"({"replica": %s, "stats": )", JsonString(replica).c_str())
                       : std::printf("== %s ==\n", replica.c_str());
      std::fflush(stdout);
      absl::StatusOr<std::shared_ptr<grpc::Channel>> channel = ConnectTo(one);
      if (!channel.ok()) return Fail(channel.status());
      auto stub = v1::Clustering::NewStub(*channel);
      grpc::ClientContext context;
      context.set_deadline(
          absl::ToChronoTime(absl::Now() + std::min(flags->deadline, absl::Seconds(10))));
      v1::Stats stats;
      grpc::Status status = stub->GetStats(&context, v1::GetStatsRequest(), &stats);
      if (!status.ok()) {
        code = 1;
        if (args.has("json")) std::printf("null}\n");
        std::fflush(stdout);
        Fail(PlainConnectionError(absl::Status(static_cast<absl::StatusCode>(status.error_code()),
                                               status.error_message()),
                                  replica));
        continue;
      }
      args.has("json") ? std::printf("%s}\n", MessageJson(stats).c_str())
                       : std::printf("%s", stats.DebugString().c_str());
    }
    return code;
  }
  absl::StatusOr<std::shared_ptr<grpc::Channel>> channel = ConnectTo(*flags);
  if (!channel.ok()) return Fail(channel.status());
  auto stub = v1::Clustering::NewStub(*channel);
  grpc::ClientContext context;
  context.set_deadline(
      absl::ToChronoTime(absl::Now() + std::min(flags->deadline, absl::Seconds(10))));
  v1::Stats stats;
  grpc::Status status = stub->GetStats(&context, v1::GetStatsRequest(), &stats);
  if (!status.ok()) {
    return Fail(PlainConnectionError(
        absl::Status(static_cast<absl::StatusCode>(status.error_code()), status.error_message()),
        address));
  }
  if (args.has("json")) {
    std::printf("%s", MessageJson(stats).c_str());
  } else {
    std::printf("%s", stats.DebugString().c_str());
  }
  return 0;
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

int Info(const Arguments& args) {
  std::unique_ptr<server::Server> embedded;
  std::shared_ptr<grpc::Channel> channel;
  const std::string address = args.get("server", "embedded");
  if (args.has("server")) {
    if (absl::Status s = CheckServerAddress(address); !s.ok()) return Fail(s);
    absl::StatusOr<ServerFlags> flags = FlagsOf(args);
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
}  // namespace mlclust::cli

namespace mlclust::cli {
namespace {

// The commands besides serve: usage, the options they accept, what runs them.
struct Command {
  std::string name;
  std::function<std::string()> usage;
  std::function<std::vector<std::string>()> known;
  int (*run)(const Arguments& args);
};

std::vector<std::string> With(std::vector<std::string> names,
                              const std::vector<std::string>& more) {
  names.insert(names.end(), more.begin(), more.end());
  return names;
}

const std::vector<Command>& Commands() {
  static const auto* commands = new std::vector<Command>{
      {"mesh", [] { return kMeshUsage + RegistryUsage(InputKind::kMesh); },
       [] {
         return With(
             With({"server",           "algo",    "energy",       "clusters",     "labels",
                   "levels-csv",       "ply",     "device",       "quiet",        "coarse",
                   "coarse-placement", "seed",    "levels",       "json",         "planar-merge",
                   "repair",           "plot",    "upload",       "quantize",     "per-polygon",
                   "detach",           "preview", "preview-size", "preview-view", "auto-k"},
                  ConnectionFlagNames()),
             RegistryOptionNames(InputKind::kMesh));
       },
       Mesh},
      {"points", [] { return kPointsUsage + RegistryUsage(InputKind::kPoints); },
       [] {
         return With(With({"server", "algo", "clusters", "labels", "levels-csv", "dims", "seed",
                           "auto-k", "levels", "quiet", "device", "json", "plot", "detach"},
                          ConnectionFlagNames()),
                     RegistryOptionNames(InputKind::kPoints));
       },
       Points},
      {"energy", [] { return std::string(kEnergyUsage); },
       [] {
         std::vector<std::string> known = {"labels", "energy"};
         for (const OptionInfo& option : EnergyOptions()) known.push_back(option.name);
         return known;
       },
       Energy},
      {"stats", [] { return std::string(kStatsUsage); },
       [] {
         return With({"server", "json"}, ConnectionFlagNames());
       },
       Stats},
      {"info", [] { return std::string(kInfoUsage); },
       [] {
         return With({"server", "json"}, ConnectionFlagNames());
       },
       Info},
  };
  return *commands;
}

const Command* FindCommand(const std::string& name) {
  for (const Command& command : Commands()) {
    if (command.name == name) return &command;
  }
  return nullptr;
}

int PrintVersion() {
  std::printf("mlclust %s\n", server::kMlclustVersion);
  return 0;
}

}  // namespace
}  // namespace mlclust::cli

int main(int argc, char** argv) {
  using namespace mlclust::cli;  // NOLINT(google-build-using-namespace): main only
  if (argc < 2) {
    PrintUsage(stderr);
    return 2;
  }
  const std::string command = argv[1];
  if (command == "--version" || command == "version") return PrintVersion();
  if (command == "help" || command == "--help" || command == "-h") {
    // `mlclust help CMD`: that command's usage; `mlclust help`: all of it.
    if (argc >= 3 && std::string(argv[2]) == "serve") {
      std::fputs(mlclust::cli::ServeUsage(), stdout);
      return 0;
    }
    if (argc >= 3 && IsJobCommand(argv[2])) {
      std::fputs(JobCommandsUsage(), stdout);
      std::fputs(ConnectionFlagsUsage(), stdout);
      return 0;
    }
    if (argc >= 3) {
      const Command* found = FindCommand(argv[2]);
      if (found == nullptr) {
        std::fprintf(stderr, "mlclust: no command '%s'; the commands: serve, %s\n", argv[2],
                     "mesh, points, energy, stats, info, watch, cancel, jobs");
        return 2;
      }
      std::fputs(found->usage().c_str(), stdout);
      return 0;
    }
    PrintUsage(stdout);
    return 0;
  }
  if (command == "serve") return RunServeCommand(argc - 2, argv + 2);
  if (IsJobCommand(command)) return RunJobCommand(command, argc - 2, argv + 2);
  const Command* found = FindCommand(command);
  if (found == nullptr) {
    std::fprintf(stderr, "mlclust: unknown command '%s'\n\n", command.c_str());
    PrintUsage(stderr);
    return 2;
  }
  absl::StatusOr<Arguments> args = Arguments::Parse(argc, argv, 2, found->known());
  if (!args.ok()) return Fail(args.status());
  if (args->has("help")) {
    std::fputs(found->usage().c_str(), stdout);
    return 0;
  }
  return found->run(*args);
}
