// The cost of the wire: the same HC job through the embedded (in-process) channel and
// through TCP on loopback, end to end from the client's side (encode, upload, decode,
// cluster, stream, rebuild).
//   wire_bench MESH [REPEATS] [hc|ml]
// Also the process's CPU time (user + sys, client and server together) of each run, the
// steadier number on a loaded machine: median of REPEATS.
#include <sys/resource.h>

#include <algorithm>
#include <cstdio>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "bench/bench_util.h"
#include "client/client.h"
#include "core/cluster/multilevel.h"
#include "core/io/draco_codec.h"
#include "core/io/mesh_io.h"
#include "core/io/prepare_mesh.h"
#include "server/server.h"

namespace {

double CpuSeconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_utime.tv_sec + usage.ru_stime.tv_sec +
         1e-6 * (usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
}

double Median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  return values[values.size() / 2];
}

bool use_ml = false;

// Keeps the levels as the client does (a HierarchyLog) with no wire in between.
double NoWireSeconds(const std::string& bytes, uint64_t* triplets) {
  const absl::Time start = absl::Now();
  absl::StatusOr<mlclust::PreparedMesh> prepared = mlclust::PrepareDracoMesh(bytes);
  if (!prepared.ok()) std::abort();
  mlclust::HierarchyLog log;
  mlclust::MultilevelOptions hc;
  if (!use_ml) hc.optimizer = mlclust::MultilevelOptions::Optimizer::kNone;
  if (!mlclust::RunMultilevel(mlclust::MakeMeshProblem(*prepared), hc, log).ok()) std::abort();
  *triplets = log.num_moves();
  return absl::ToDoubleSeconds(absl::Now() - start);
}

}  // namespace

int main(int argc, char** argv) {
  mlclust::bench::Args args(argc, argv, "usage: wire_bench MESH [REPEATS] [hc|ml]");
  const std::string path = args.Positional(0);
  int repeats = 3;
  if (args.num_positional() > 1 && !absl::SimpleAtoi(args.Positional(1), &repeats)) return 2;
  if (args.num_positional() > 2) use_ml = args.Positional(2) == "ml";
  if (!args.Done()) return 2;
  absl::StatusOr<mlclust::TriangleMesh> mesh = mlclust::ReadMeshFile(path);
  if (!mesh.ok()) return 1;
  const absl::Time encode_start = absl::Now();
  absl::StatusOr<std::string> bytes = mlclust::EncodeMeshToDraco(*mesh);
  const double encode = absl::ToDoubleSeconds(absl::Now() - encode_start);
  if (!bytes.ok()) return 1;

  mlclust::server::ServerOptions options;
  options.listen_address = "127.0.0.1:0";
  options.log = false;
  auto server = mlclust::server::Server::Start(options);
  if (!server.ok()) return 1;
  std::printf("%s: %zu faces, Draco %zu bytes (encoded in %.3f s); GL: %s\n", path.c_str(),
              mesh->num_faces(), bytes->size(), encode,
              (*server)->gl_renderer().empty() ? "none" : (*server)->gl_renderer().c_str());

  mlclust::v1::JobSpec spec;
  spec.set_input_kind(mlclust::v1::INPUT_KIND_DRACO_MESH);
  spec.set_algorithm(use_ml ? mlclust::v1::ALGORITHM_ML : mlclust::v1::ALGORITHM_HC);
  // Each route with the repeated (varint) triplets and with JobSpec.packed_triplets.
  struct Route {
    const char* name;
    std::shared_ptr<grpc::Channel> channel;
    bool packed;
  };
  const std::shared_ptr<grpc::Channel> tcp =
      mlclust::client::Connect(absl::StrCat("127.0.0.1:", (*server)->port()));
  const Route routes[] = {
      {"embedded varint", (*server)->InProcessChannel(), false},
      {"embedded packed", (*server)->InProcessChannel(), true},
      {"tcp varint", tcp, false},
      {"tcp packed", tcp, true},
  };
  double no_wire = 1e30;
  uint64_t no_wire_triplets = 0;
  std::vector<double> no_wire_cpu;
  for (int r = 0; r < repeats; ++r) {
    const double cpu = CpuSeconds();
    no_wire = std::min(no_wire, NoWireSeconds(*bytes, &no_wire_triplets));
    no_wire_cpu.push_back(CpuSeconds() - cpu);
  }
  std::printf(
      "%-15s decode + validate + %s into a HierarchyLog in one process: %.3f s, %llu "
      "triplets; best of %d; CPU %.3f s (median)\n",
      "no wire", use_ml ? "ML" : "HC", no_wire, static_cast<unsigned long long>(no_wire_triplets),
      repeats, Median(no_wire_cpu));
  for (const Route& route : routes) {
    double best = 1e30, server_running = 0;
    uint64_t triplets = 0;
    std::vector<double> cpu_seconds;
    for (int r = 0; r < repeats; ++r) {
      const double cpu = CpuSeconds();
      const absl::Time start = absl::Now();
      mlclust::client::RunOptions run_options;
      run_options.packed_triplets = route.packed;
      auto result = mlclust::client::RunJob(route.channel, spec, *bytes, run_options);
      const double seconds = absl::ToDoubleSeconds(absl::Now() - start);
      cpu_seconds.push_back(CpuSeconds() - cpu);
      if (!result.ok()) {
        std::fprintf(stderr, "%s\n", result.status().ToString().c_str());
        return 1;
      }
      if (seconds < best) {
        best = seconds;
        server_running = result->done.seconds_running();
        triplets = result->hierarchy.num_moves();
      }
    }
    // Levels stream while HC runs, so the wire's cost is what end to end adds beyond the
    // same work in one process.
    std::printf(
        "%-15s end to end %.3f s (server side %.3f s), %llu triplets = %.2f M "
        "triplets/s end to end; the wire adds %+.3f s; best of %d; CPU %.3f s (median), "
        "%+.3f s over no wire\n",
        route.name, best, server_running, static_cast<unsigned long long>(triplets),
        triplets / best / 1e6, best - no_wire, repeats, Median(cpu_seconds),
        Median(cpu_seconds) - Median(no_wire_cpu));
  }
  return 0;
}
