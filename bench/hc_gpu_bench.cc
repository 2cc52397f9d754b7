// HC for meshes (merges only, CVD, one merge per level) on the GPU
// (gpu/stages/hierarchy_gpu.h) against the CPU engine's HC: wall time and process CPU time
// of the whole hierarchy (for the GPU: upload, every step, every triplet read back; on
// llvmpipe the CPU time includes its threads), levels, final energy, and how many levels
// have the same triplets on both (an order-independent fingerprint per level) and the
// same energy to the last digit.
//
//   hc_gpu_bench MESH [--lowest K] [--energy cvd|cvd-adaptive] [--repeats R] [--header]
//
// Prints one CSV row per device (best of R runs, wall and CPU taken from the same run):
// mesh,faces,device,energy,seconds,cpu_seconds,levels,final_clusters,final_energy,
// same_levels,same_energies
#include <cstdio>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "bench/bench_util.h"
#include "bench/gpu_bench_util.h"
#include "core/cluster/multilevel.h"
#include "gpu/context/gl_context.h"
#include "gpu/stages/hierarchy_gpu.h"

namespace {

// Per level an order-independent fingerprint of its triplets and its cluster count, and
// its energy.
class FingerprintSink : public mlclust::LevelSink {
 public:
  absl::Status OnStart(std::span<const mlclust::ClusterId> /*labels*/, uint32_t count,
                       double energy) override {
    prints.push_back(count);
    energies.push_back(energy);
    return absl::OkStatus();
  }
  absl::Status OnLevel(const mlclust::LevelMoves& level) override {
    prints.push_back(mlclust::bench::LevelFingerprint(level));
    energies.push_back(level.energy);
    return absl::OkStatus();
  }
  std::vector<uint64_t> prints;
  std::vector<double> energies;
};

}  // namespace

int main(int argc, char** argv) {
  mlclust::bench::Args args(argc, argv,
                            "usage: hc_gpu_bench MESH [--lowest K] [--energy cvd|cvd-adaptive] "
                            "[--repeats R] [--header]");
  const bool header = args.Flag("header");
  const uint32_t lowest = args.Get<uint32_t>("lowest", 1);
  const std::string energy = args.Get<std::string>("energy", "cvd");
  const uint32_t repeats = args.Get<uint32_t>("repeats", 1);
  const std::string path = args.Positional(0);
  if (!args.Done()) return 2;

  const mlclust::PreparedMesh prepared = mlclust::bench::PrepareOrDie(path);
  mlclust::MeshEnergyOptions energy_options;
  energy_options.kind = energy == "cvd-adaptive" ? mlclust::MeshEnergyKind::kCvdAdaptive
                                                 : mlclust::MeshEnergyKind::kCvd;
  const mlclust::MeshProblem problem = mlclust::MakeMeshProblem(prepared, energy_options);
  mlclust::MultilevelOptions options;
  options.optimizer = mlclust::MultilevelOptions::Optimizer::kNone;
  options.min_clusters = lowest;
  const std::unique_ptr<mlclust::gpu::GlContext> context = mlclust::bench::GlContextOrPrint();
  if (context == nullptr) return 1;
  struct Row {
    std::string device;
    double seconds = std::numeric_limits<double>::infinity();
    double cpu_seconds = 0;
    mlclust::MultilevelSummary summary;
    FingerprintSink sink;
  };
  Row rows[2];
  rows[0].device = "cpu";
  rows[1].device = context->renderer();
  for (int d = 0; d < 2; ++d) {
    for (uint32_t r = 0; r < repeats; ++r) {
      FingerprintSink sink;
      const double cpu = mlclust::bench::ProcessCpuSeconds();
      const mlclust::bench::Stopwatch watch;
      absl::StatusOr<mlclust::MultilevelSummary> summary =
          d == 0 ? mlclust::RunMultilevel(problem, options, sink)
                 : mlclust::gpu::RunHierarchyGpu(*context, problem, options, sink);
      const double seconds = watch.Seconds();
      const double cpu_seconds = mlclust::bench::ProcessCpuSeconds() - cpu;
      if (!summary.ok()) {
        std::fprintf(stderr, "%s\n", summary.status().ToString().c_str());
        return 1;
      }
      if (seconds < rows[d].seconds) {
        rows[d].seconds = seconds;
        rows[d].cpu_seconds = cpu_seconds;
      }
      rows[d].summary = *summary;
      rows[d].sink = std::move(sink);
    }
  }
  size_t same = 0, same_energies = 0;
  const FingerprintSink &cpu = rows[0].sink, &gpu = rows[1].sink;
  for (size_t l = 0; l < cpu.prints.size() && l < gpu.prints.size(); ++l) {
    same += cpu.prints[l] == gpu.prints[l] ? 1 : 0;
    same_energies += cpu.energies[l] == gpu.energies[l] ? 1 : 0;
  }
  if (header) {
    std::printf(
        "mesh,faces,device,energy,seconds,cpu_seconds,levels,final_clusters,final_energy,"
        "same_levels,same_energies\n");
  }
  const std::string name = mlclust::bench::BaseName(path);
  for (const Row& row : rows) {
    std::printf("%s,%zu,\"%s\",%s,%.3f,%.3f,%u,%u,%.10g,%zu,%zu\n", name.c_str(),
                prepared.mesh.num_faces(), row.device.c_str(), energy.c_str(), row.seconds,
                row.cpu_seconds, row.summary.levels, row.summary.final_clusters,
                row.summary.final_energy, same, same_energies);
  }
  return 0;
}
