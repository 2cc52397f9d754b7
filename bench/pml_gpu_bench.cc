// PML for meshes (CVD) on the GPU (gpu/stages/multilevel_gpu.h) against the CPU engine's
// PML with the same options on T threads: wall time of the whole hierarchy (for the GPU:
// upload, every level, every triplet read back), levels, final energy, and how many levels
// have the same triplets on both (an order-independent fingerprint per level). With
// --optimizer bb, Alg. 5.7: BB sweeps after each level (the CPU engine's are local
// one-by-one sweeps, the GPU's Alg. 5.4 sweeps over every face, so the levels differ).
// With --algo ml (Alg. 5.6, RunMultilevelGpu; optimizer none is HC's steps): one merge per
// level, against the CPU engine's ML with the same optimizer (pairs and threads unused);
// --clusters K stops both at K clusters (default 1: the whole hierarchy).
//
//   pml_gpu_bench MESH [--algo pml|ml] [--pairs all|cheaper-half] [--optimizer none|bb]
//                 [--threads T] [--repeats R] [--at K] [--clusters K] [--header]
//
// Prints one CSV row per device (best time of R runs; cpu_seconds: the process's CPU time
// of that run, every thread, llvmpipe's included):
// mesh,faces,device,pairs,threads,seconds,levels,final_clusters,final_energy,same_levels,
// optimizer,cpu_seconds,at_clusters,at_energy (pairs: ml with --algo ml)
// (at_clusters, at_energy: the energy at --at K clusters, default 1000, a power law between
// the two levels around K (log energy linear in log count), or the first level with at most
// K clusters where there is no level before it with more: where the optimisers' levels
// differ, their energies compare there.)
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "bench/bench_util.h"
#include "bench/gpu_bench_util.h"
#include "core/cluster/multilevel.h"
#include "gpu/context/gl_context.h"
#include "gpu/stages/multilevel_gpu.h"
#include "tests/fixtures/energy_at_count.h"

namespace {

// Per level an order-independent fingerprint of its triplets and its cluster count
// (LevelPrintSink); the first level with at most `at` clusters.
class FingerprintSink : public mlclust::bench::LevelPrintSink {
 public:
  explicit FingerprintSink(uint32_t at) : at_(at) {}
  absl::Status OnStart(std::span<const mlclust::ClusterId> labels, uint32_t count,
                       double energy) override {
    previous_count_ = count;
    return LevelPrintSink::OnStart(labels, count, energy);
  }
  absl::Status OnLevel(const mlclust::LevelMoves& level) override {
    if (at_count == 0 && level.cluster_count <= at_) {
      at_count = level.cluster_count;
      at_energy = level.energy;
      // At exactly `at` clusters: a power law through this level and the one before.
      if (level.cluster_count < at_ && previous_count_ > at_ && previous_energy_ > 0 &&
          level.energy > 0) {
        at_count = at_;
        at_energy = mlclust::testing::PowerLawEnergyAt(at_, previous_count_, previous_energy_,
                                                       level.cluster_count, level.energy);
      }
    }
    previous_count_ = level.cluster_count;
    previous_energy_ = level.energy;
    return LevelPrintSink::OnLevel(level);
  }
  uint32_t at_count = 0;
  double at_energy = 0;

 private:
  uint32_t at_;
  uint32_t previous_count_ = 0;
  double previous_energy_ = 0;
};

}  // namespace

int main(int argc, char** argv) {
  mlclust::bench::Args args(argc, argv,
                            "usage: pml_gpu_bench MESH [--algo pml|ml] [--pairs "
                            "all|cheaper-half] [--optimizer none|bb] [--threads T] [--repeats R] "
                            "[--at K] [--clusters K] [--header]");
  const bool header = args.Flag("header");
  const std::string pairs = args.Get<std::string>("pairs", "all");
  const std::string optimizer = args.Get<std::string>("optimizer", "none");
  const int threads = args.Get<int>("threads", 0);
  const uint32_t repeats = args.Get<uint32_t>("repeats", 1);
  const uint32_t at = args.Get<uint32_t>("at", 1000);
  const std::string algo = args.Get<std::string>("algo", "pml");
  const uint32_t clusters = args.Get<uint32_t>("clusters", 1);
  const std::string path = args.Positional(0);
  if (!args.Done()) return 2;
  if (optimizer != "none" && optimizer != "bb") {
    std::fprintf(stderr, "--optimizer: '%s' is not none or bb\n", optimizer.c_str());
    return 2;
  }
  if (algo != "pml" && algo != "ml") {
    std::fprintf(stderr, "--algo: '%s' is not pml or ml\n", algo.c_str());
    return 2;
  }
  const bool ml = algo == "ml";

  const mlclust::PreparedMesh prepared = mlclust::bench::PrepareOrDie(path);
  const mlclust::MeshProblem problem = mlclust::MakeMeshProblem(prepared, {});
  mlclust::MultilevelOptions options;
  options.parallel = !ml;
  options.min_clusters = clusters;
  options.optimizer = optimizer == "bb" ? mlclust::MultilevelOptions::Optimizer::kBoundaryBased
                                        : mlclust::MultilevelOptions::Optimizer::kNone;
  options.pml_pairs =
      pairs == "cheaper-half" ? mlclust::PmlPairRule::kCheaperHalf : mlclust::PmlPairRule::kAll;
  options.threads = threads;
  const std::unique_ptr<mlclust::gpu::GlContext> context = mlclust::bench::GlContextOrPrint();
  if (context == nullptr) return 1;
  const auto rows = mlclust::bench::RunOnCpuAndGpu<mlclust::MultilevelSummary, FingerprintSink>(
      *context, repeats, [at] { return FingerprintSink(at); },
      [&](int device, FingerprintSink& sink) {
        return device == 0 ? mlclust::RunMultilevel(problem, options, sink)
               : ml        ? mlclust::gpu::RunMultilevelGpu(*context, problem, options, sink)
                    : mlclust::gpu::RunParallelMultilevelGpu(*context, problem, options, sink);
      });
  if (!rows) return 1;
  const size_t same = mlclust::bench::SameLevels((*rows)[0].sink->prints, (*rows)[1].sink->prints);
  if (header) {
    std::printf(
        "mesh,faces,device,pairs,threads,seconds,levels,final_clusters,final_energy,"
        "same_levels,optimizer,cpu_seconds,at_clusters,at_energy\n");
  }
  const std::string name = path.substr(path.find_last_of('/') + 1);
  for (const auto& row : *rows) {
    std::printf("%s,%zu,\"%s\",%s,%d,%.3f,%u,%u,%.10g,%zu,%s,%.3f,%u,%.10g\n", name.c_str(),
                prepared.mesh.num_faces(), row.device.c_str(), ml ? "ml" : pairs.c_str(), threads,
                row.seconds, row.summary.levels, row.summary.final_clusters,
                row.summary.final_energy, same, optimizer.c_str(), row.cpu_seconds,
                row.sink->at_count, row.sink->at_energy);
  }
  return 0;
}
