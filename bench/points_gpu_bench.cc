// PML for points on the GPU (gpu/stages/points_multilevel_gpu.h: the voxel start and every
// level on the GPU; merges only, or with --optimizer lnkmeans the CPU's LN k-means rounds
// after each level, gpu/stages/points_optimise_gpu.h) against the CPU engine's PML with the same
// options (core/cluster/point_clustering.h, RunPointMultilevel) on T threads, on Gaussian blobs:
// the whole hierarchy (for the GPU: upload, start, every level, every triplet read back),
// wall seconds and the process's CPU seconds (llvmpipe's threads included), levels, the
// energy at the lowest level, at 4x and 16x its clusters and at the number of blobs.
//
//   points_gpu_bench [--m M] [--d D] [--blobs B] [--algo pml|hc|ml]
//                    [--pairs all|cheaper-half] [--until K] [--pml-until N]
//                    [--optimizer none|lnkmeans]
//                    [--bounded F] [--threads T] [--repeats R] [--seed S] [--curve] [--header]
//
// --algo hc (merges only) and ml (LN k-means unless --optimizer none) run one merge per
// level (RunPointHierarchyGpu against the CPU engine's HC / ML); the row's `same_levels`
// is the number of leading levels (level 0 included) the two devices agree on exactly
// (counts and triplets; the CPU's row: its own levels).
//
// Prints one CSV row per device (best wall time of R runs):
// points,dims,blobs,device,pairs,threads,seconds,cpu_seconds,levels,start_clusters,
// final_clusters,energy_final,energy_4x,energy_16x,energy_at_blobs,optimizer,algo,
// same_levels,largest_energy_ratio (GPU / CPU at the CPU's counts, the largest |r - 1|)
#include <algorithm>
#include <array>
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

// Per level its cluster count and energy, and a hash of its triplets.
class CurveSink : public mlclust::LevelSink {
 public:
  absl::Status OnStart(std::span<const mlclust::ClusterId> /*labels*/, uint32_t count,
                       double energy) override {
    counts.push_back(count);
    energies.push_back(energy);
    hashes.push_back(count);
    return absl::OkStatus();
  }
  absl::Status OnLevel(const mlclust::LevelMoves& level) override {
    counts.push_back(level.cluster_count);
    energies.push_back(level.energy);
    // FNV-1a over the triplets sorted by element (their order differs between devices).
    std::vector<std::array<uint32_t, 3>> sorted;
    for (size_t t = 0; t < level.element.size(); ++t) {
      sorted.push_back({level.element[t], level.to_cluster[t], level.from_cluster[t]});
    }
    std::sort(sorted.begin(), sorted.end());
    uint64_t hash = 1469598103934665603ull;
    for (const auto& triplet : sorted) {
      for (const uint32_t v : triplet) hash = (hash ^ v) * 1099511628211ull;
    }
    hashes.push_back(hash);
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
  std::vector<uint64_t> hashes;
};

}  // namespace

int main(int argc, char** argv) {
  mlclust::bench::Args args(
      argc, argv,
      "usage: points_gpu_bench [--m M] [--d D] [--blobs B] "
      "[--algo pml|hc|ml] [--pairs all|cheaper-half] [--until K] [--pml-until N] "
      "[--optimizer none|lnkmeans] [--bounded F] [--threads T] [--repeats R] "
      "[--seed S] [--curve] [--header]");
  const bool header = args.Flag("header");
  const bool curve = args.Flag("curve");  // every level's count and energy to stderr
  const uint64_t m = args.Get<uint64_t>("m", 100000);
  const uint32_t d = args.Get<uint32_t>("d", 3), blobs = args.Get<uint32_t>("blobs", 1000);
  const std::string pairs = args.Get<std::string>("pairs", "cheaper-half");
  const uint32_t until = args.Get<uint32_t>("until", 1);
  const uint32_t pml_until = args.Get<uint32_t>("pml-until", 0);  // --algo pml: then ML
  const std::string algo = args.Get<std::string>("algo", "pml");
  // PML's default is merges only (as before --algo); ML's is LN k-means; HC has none.
  const std::string optimizer =
      args.Get<std::string>("optimizer", algo == "ml" ? "lnkmeans" : "none");
  const double bounded = args.Get<double>("bounded", 0.0);
  const int threads = args.Get<int>("threads", 0);
  const uint32_t repeats = args.Get<uint32_t>("repeats", 1);
  const uint64_t seed = args.Get<uint64_t>("seed", 1);
  if (!args.Done()) return 2;
  if (pairs != "all" && pairs != "cheaper-half") {
    std::fprintf(stderr, "bad option --pairs %s\n", pairs.c_str());
    return 2;
  }
  if (algo != "pml" && algo != "hc" && algo != "ml") {
    std::fprintf(stderr, "bad option --algo %s\n", algo.c_str());
    return 2;
  }
  if ((optimizer != "none" && optimizer != "lnkmeans") || (algo == "hc" && optimizer != "none")) {
    std::fprintf(stderr, "bad option --optimizer %s\n", optimizer.c_str());
    return 2;
  }
  const mlclust::PointSet points = mlclust::bench::Blobs(m, d, blobs, seed);
  mlclust::PointMultilevelOptions options;
  options.parallel = algo == "pml";
  options.bounded_drift = bounded;
  options.pml_until = pml_until;
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
        if (device == 0) return mlclust::RunPointMultilevel(points, options, sink);
        return options.parallel
                   ? mlclust::gpu::RunPointParallelMultilevelGpu(*context, points, options, sink)
                   : mlclust::gpu::RunPointHierarchyGpu(*context, points, options, sink);
      });
  if (!rows) return 1;
  if (header) {
    std::printf(
        "points,dims,blobs,device,pairs,threads,seconds,cpu_seconds,levels,start_clusters,"
        "final_clusters,energy_final,energy_4x,energy_16x,energy_at_blobs,optimizer,algo,"
        "same_levels,largest_energy_ratio\n");
  }
  const CurveSink& cpu = *rows->front().sink;
  for (const auto& row : *rows) {
    const CurveSink& sink = *row.sink;
    for (size_t l = 0; curve && l < sink.counts.size(); ++l) {
      std::fprintf(stderr, "%s,%zu,%u,%.8g\n", row.device.c_str(), l, sink.counts[l],
                   sink.energies[l]);
    }
    const uint32_t low = row.summary.final_clusters;
    size_t same = 0;
    while (same < sink.hashes.size() && same < cpu.hashes.size() &&
           sink.hashes[same] == cpu.hashes[same] && sink.counts[same] == cpu.counts[same]) {
      ++same;
    }
    double largest = 0;
    for (size_t l = 0; l < cpu.counts.size(); ++l) {
      largest = std::max(largest, std::abs(sink.At(cpu.counts[l]) / cpu.energies[l] - 1));
    }
    std::printf("%llu,%u,%u,\"%s\",%s,%d,%.3f,%.3f,%u,%u,%u,%.8g,%.8g,%.8g,%.8g,%s,%s,%zu,%.3g\n",
                static_cast<unsigned long long>(m), d, blobs, row.device.c_str(), pairs.c_str(),
                threads, row.seconds, row.cpu_seconds, row.summary.levels,
                row.summary.start_clusters, low, sink.energies.back(), sink.At(4 * low),
                sink.At(16 * low), sink.At(blobs), optimizer.c_str(), algo.c_str(), same, largest);
  }
  return 0;
}
