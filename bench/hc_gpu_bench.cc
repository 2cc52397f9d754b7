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
#include <memory>
#include <string>
#include <vector>

#include "bench/bench_util.h"
#include "bench/gpu_bench_util.h"
#include "core/cluster/multilevel.h"
#include "gpu/context/gl_context.h"
#include "gpu/stages/hierarchy_gpu.h"

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
  using Sink = mlclust::bench::LevelPrintSink;
  const auto rows = mlclust::bench::RunOnCpuAndGpu<mlclust::MultilevelSummary, Sink>(
      *context, repeats, [] { return Sink(); },
      [&](int device, Sink& sink) {
        return device == 0 ? mlclust::RunMultilevel(problem, options, sink)
                           : mlclust::gpu::RunHierarchyGpu(*context, problem, options, sink);
      });
  if (!rows) return 1;
  const Sink &cpu = *(*rows)[0].sink, &gpu = *(*rows)[1].sink;
  const size_t same = mlclust::bench::SameLevels(cpu.prints, gpu.prints);
  const size_t same_energies = mlclust::bench::SameLevels(cpu.energies, gpu.energies);
  if (header) {
    std::printf(
        "mesh,faces,device,energy,seconds,cpu_seconds,levels,final_clusters,final_energy,"
        "same_levels,same_energies\n");
  }
  const std::string name = mlclust::bench::BaseName(path);
  for (const auto& row : *rows) {
    std::printf("%s,%zu,\"%s\",%s,%.3f,%.3f,%u,%u,%.10g,%zu,%zu\n", name.c_str(),
                prepared.mesh.num_faces(), row.device.c_str(), energy.c_str(), row.seconds,
                row.cpu_seconds, row.summary.levels, row.summary.final_clusters,
                row.summary.final_energy, same, same_energies);
  }
  return 0;
}
