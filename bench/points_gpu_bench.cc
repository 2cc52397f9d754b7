// PML for points on the GPU (gpu/stages/points_multilevel_gpu.h: the voxel start and every
// level on the GPU; merges only, or with --optimizer lnkmeans the CPU's LN k-means rounds
// after each level, gpu/stages/points_optimise_gpu.h) against the CPU engine's PML with the same
// options (core/cluster/point_clustering.h, RunPointMultilevel) on T threads, on Gaussian blobs:
// the whole hierarchy (for the GPU: upload, start, every level, every triplet read back),
// wall seconds and the process's CPU seconds (llvmpipe's threads included), levels, the
// energy at the lowest level, at 4x and 16x its clusters and at the number of blobs.
//
//   points_gpu_bench [--m M] [--d D] [--blobs B] [--pairs all|cheaper-half] [--until K]
//                    [--optimizer none|lnkmeans] [--threads T] [--repeats R] [--seed S]
//                    [--curve] [--header]
//
// Prints one CSV row per device (best wall time of R runs):
// points,dims,blobs,device,pairs,threads,seconds,cpu_seconds,levels,start_clusters,
// final_clusters,energy_final,energy_4x,energy_16x,energy_at_blobs,optimizer
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "bench/bench_util.h"
#include "bench/blobs.h"
#include "bench/gpu_bench_util.h"
#include "core/cluster/point_clustering.h"
#include "gpu/context/gl_context.h"
#include "gpu/stages/points_multilevel_gpu.h"

namespace {

// Per level its cluster count and energy.
class CurveSink : public mlclust::LevelSink {
 public:
  absl::Status OnStart(std::span<const mlclust::ClusterId> /*labels*/, uint32_t count,
                       double energy) override {
    counts.push_back(count);
    energies.push_back(energy);
    return absl::OkStatus();
  }
  absl::Status OnLevel(const mlclust::LevelMoves& level) override {
    counts.push_back(level.cluster_count);
    energies.push_back(level.energy);
    return absl::OkStatus();
  }
  // The energy of the last level with at least `count` clusters.
  double At(uint32_t count) const {
    double energy = energies.front();
    for (size_t l = 0; l < counts.size() && counts[l] >= count; ++l) energy = energies[l];
    return energy;
  }
  std::vector<uint32_t> counts;
  std::vector<double> energies;
};

}  // namespace

int main(int argc, char** argv) {
  mlclust::bench::Args args(argc, argv,
                            "usage: points_gpu_bench [--m M] [--d D] [--blobs B] "
                            "[--pairs all|cheaper-half] [--until K] [--optimizer none|lnkmeans] "
                            "[--threads T] [--repeats R] "
                            "[--seed S] [--curve] [--header]");
  const bool header = args.Flag("header");
  const bool curve = args.Flag("curve");  // every level's count and energy to stderr
  const uint64_t m = args.Get<uint64_t>("m", 100000);
  const uint32_t d = args.Get<uint32_t>("d", 3), blobs = args.Get<uint32_t>("blobs", 1000);
  const std::string pairs = args.Get<std::string>("pairs", "cheaper-half");
  const uint32_t until = args.Get<uint32_t>("until", 1);
  const std::string optimizer = args.Get<std::string>("optimizer", "none");
  const int threads = args.Get<int>("threads", 0);
  const uint32_t repeats = args.Get<uint32_t>("repeats", 1);
  const uint64_t seed = args.Get<uint64_t>("seed", 1);
  if (!args.Done()) return 2;
  if (pairs != "all" && pairs != "cheaper-half") {
    std::fprintf(stderr, "bad option --pairs %s\n", pairs.c_str());
    return 2;
  }
  if (optimizer != "none" && optimizer != "lnkmeans") {
    std::fprintf(stderr, "bad option --optimizer %s\n", optimizer.c_str());
    return 2;
  }
  const mlclust::PointSet points = mlclust::bench::Blobs(m, d, blobs, seed);
  mlclust::PointMultilevelOptions options;
  options.parallel = true;
  options.optimizer = optimizer == "none" ? mlclust::PointMultilevelOptions::Optimizer::kNone
                                          : mlclust::PointMultilevelOptions::Optimizer::kLnKmeans;
  options.pml_pairs =
      pairs == "all" ? mlclust::PmlPairRule::kAll : mlclust::PmlPairRule::kCheaperHalf;
  options.min_clusters = std::max(until, 1u);
  options.threads = threads;
  const std::unique_ptr<mlclust::gpu::GlContext> context = mlclust::bench::GlContextOrPrint();
  if (context == nullptr) return 1;
  const auto rows = mlclust::bench::RunOnCpuAndGpu<mlclust::PointMultilevelSummary, CurveSink>(
      *context, repeats, [] { return CurveSink(); },
      [&](int device, CurveSink& sink) {
        return device == 0
                   ? mlclust::RunPointMultilevel(points, options, sink)
                   : mlclust::gpu::RunPointParallelMultilevelGpu(*context, points, options, sink);
      });
  if (!rows) return 1;
  if (header) {
    std::printf(
        "points,dims,blobs,device,pairs,threads,seconds,cpu_seconds,levels,start_clusters,"
        "final_clusters,energy_final,energy_4x,energy_16x,energy_at_blobs,optimizer\n");
  }
  for (const auto& row : *rows) {
    const CurveSink& sink = *row.sink;
    for (size_t l = 0; curve && l < sink.counts.size(); ++l) {
      std::fprintf(stderr, "%s,%zu,%u,%.8g\n", row.device.c_str(), l, sink.counts[l],
                   sink.energies[l]);
    }
    const uint32_t low = row.summary.final_clusters;
    std::printf("%llu,%u,%u,\"%s\",%s,%d,%.3f,%.3f,%u,%u,%u,%.8g,%.8g,%.8g,%.8g,%s\n",
                static_cast<unsigned long long>(m), d, blobs, row.device.c_str(), pairs.c_str(),
                threads, row.seconds, row.cpu_seconds, row.summary.levels,
                row.summary.start_clusters, low, sink.energies.back(), sink.At(4 * low),
                sink.At(16 * low), sink.At(blobs), optimizer.c_str());
  }
  return 0;
}
