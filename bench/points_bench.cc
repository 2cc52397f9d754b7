// Times point clustering on synthetic Gaussian blobs, or on a file (.npy, .csv, or raw
// float32 with --dims: the files bench/points_data.py writes, which the Python peers read).
//   points_bench --algo ml|pml|hc|lnkmeans|kmeans [--m M] [--d D] [--blobs K] [--k K]
//                [--init kmeans++|random] [--grid A] [--threads T] [--seed S]
//                [--input FILE [--dims D]] [--until K] [--curve CSV] [--fingerprint 1]
//                [--rounds R] [--bounded F]
// --until K stops the hierarchy at K clusters (for time per step at high d); --curve writes
// every level's clusters,energy. --fingerprint 1 prints on stderr a 64-bit FNV-1a hash over
// every level's cluster count, energy bits and triplets (as bench/engine_golden does), to
// compare two builds on large sets. --rounds R: PointMultilevelOptions::optimise_rounds;
// --bounded F: PointMultilevelOptions::bounded_drift (ours; 0, default: off).
// --cancel-after S sets the options' cancel flag S seconds
// into the clustering (after the set-up) and reports on stderr how long the call took to
// return after it (then exits).
// Prints one CSV row:
//   algo,m,d,blobs,k,grid,threads,seconds,init_seconds,steps,energy,start_clusters
// seconds: end to end (for lnkmeans/kmeans the seeding included, init_seconds of it);
// steps: levels of the hierarchy or iterations; energy: at the first level with at most k
// clusters, or of the k-means result.
#include <algorithm>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <string>

#include "bench/bench_util.h"
#include "bench/blobs.h"
#include "bench/cancel_timer.h"
#include "bench/curve_sink.h"
#include "bench/level_hash.h"
#include "core/cluster/kmeans.h"
#include "core/cluster/point_clustering.h"

namespace {

// The curve, and with `hash` set an FNV-1a hash over every level (counts, energy bits,
// start labels and triplets).
class CurveSink : public mlclust::bench::CurveSink {
 public:
  explicit CurveSink(bool hash) : hash_(hash) {}
  absl::Status OnStart(std::span<const mlclust::ClusterId> labels, uint32_t count,
                       double energy) override {
    if (hash_) levels_.Start(labels, count, energy);
    return mlclust::bench::CurveSink::OnStart(labels, count, energy);
  }
  absl::Status OnLevel(const mlclust::LevelMoves& level) override {
    if (hash_) levels_.Level(level);
    return mlclust::bench::CurveSink::OnLevel(level);
  }
  uint64_t hash() const { return levels_.value(); }

 private:
  bool hash_;
  mlclust::bench::LevelHash levels_;
};

}  // namespace

int main(int argc, char** argv) {
  mlclust::bench::Args args(
      argc, argv,
      "usage: points_bench --algo ml|pml|hc|lnkmeans|kmeans [--m M] [--d D] [--blobs K] [--k K] "
      "[--init kmeans++|random] [--grid A] [--threads T] [--seed S] [--input FILE [--dims D]] "
      "[--until K] [--curve CSV] [--fingerprint 1] [--rounds R] [--bounded F] "
      "[--cancel-after S]");
  const std::string algo = args.Get<std::string>("algo", "ml");
  uint64_t m = args.Get<uint64_t>("m", 100000);
  const uint64_t seed = args.Get<uint64_t>("seed", 1);
  uint32_t d = args.Get<uint32_t>("d", 3), blobs = args.Get<uint32_t>("blobs", 100);
  const uint32_t k = args.Get<uint32_t>("k", 1000), grid = args.Get<uint32_t>("grid", 0);
  const uint32_t dims = args.Get<uint32_t>("dims", 0), until = args.Get<uint32_t>("until", 1);
  const uint32_t rounds = args.Get<uint32_t>("rounds", 8);
  const double bounded = args.Get<double>("bounded", 0);
  const int threads = args.Get<int>("threads", 0), fingerprint = args.Get<int>("fingerprint", 0);
  const double cancel_after = args.Get<double>("cancel-after", -1);
  const std::string input = args.Get<std::string>("input", "");
  const std::string init = args.Get<std::string>("init", "kmeans++");
  const std::string curve = args.Get<std::string>("curve", "");
  if (!args.Done()) return 2;
  if (init != "kmeans++" && init != "random") {
    std::fprintf(stderr, "bad option --init %s\n", init.c_str());
    return 2;
  }
  mlclust::PointSet points;
  if (!input.empty()) {
    points = mlclust::bench::ReadPointsOrDie(input, dims);
    m = points.num_points();
    d = points.dims;
    blobs = 0;
  } else {
    points = mlclust::bench::Blobs(m, d, blobs, seed);
  }
  const mlclust::bench::Stopwatch watch;
  uint64_t steps = 0;
  double energy = 0, init_seconds = 0;
  uint32_t used_grid = grid, start_clusters = 0;
  if (algo == "lnkmeans" || algo == "kmeans") {
    auto centres = init == "kmeans++" ? mlclust::KmeansPlusPlusCentres(points, k, seed, threads)
                                      : mlclust::RandomPointCentres(points, k, seed);
    if (!centres.ok()) {
      std::fprintf(stderr, "%s\n", centres.status().ToString().c_str());
      return 1;
    }
    init_seconds = watch.Seconds();
    mlclust::KmeansOptions lloyd;
    lloyd.clusters = k;
    lloyd.threads = threads;
    if (algo == "lnkmeans") lloyd.max_iterations = 1;  // the assignment to the seeds
    auto assigned = mlclust::RunLloyd(points, *centres, lloyd);
    if (!assigned.ok()) return 1;
    start_clusters = k;
    if (algo == "kmeans") {
      steps = assigned->iterations;
      std::fprintf(stderr, "kmeans: %u iterations in %.3f s (mean %.4f s)\n", assigned->iterations,
                   assigned->seconds_iterations,
                   assigned->seconds_iterations / std::max(assigned->iterations, 1u));
      energy = mlclust::PointEnergy(points, assigned->labels);
    } else {
      mlclust::LnKmeansOptions options;
      options.threads = threads;
      // Per-iteration times (the on_iteration callback's own energy sum excluded).
      std::vector<double> iteration_seconds;
      mlclust::bench::Stopwatch since_last;
      options.on_iteration = [&](uint32_t, uint64_t, double) {
        iteration_seconds.push_back(since_last.Seconds());
        since_last.Restart();
      };
      const mlclust::bench::Stopwatch iterations;
      mlclust::bench::CancelTimer cancel(cancel_after);
      options.cancel = cancel.flag();
      auto result = mlclust::RunLnKmeans(points, assigned->labels, options);
      if (cancel_after >= 0) {
        cancel.Report(result.status(), "RunLnKmeans");
        return 0;
      }
      if (!result.ok()) return 1;
      const double iterate = iterations.Seconds();
      if (!iteration_seconds.empty()) {
        std::fprintf(stderr,
                     "lnkmeans: %zu iterations in %.3f s (first %.4f s, mean %.4f s, "
                     "slowest %.4f s)\n",
                     iteration_seconds.size(), iterate, iteration_seconds.front(),
                     iterate / iteration_seconds.size(),
                     *std::max_element(iteration_seconds.begin(), iteration_seconds.end()));
      }
      steps = result->iterations;
      energy = result->energy;
    }
  } else {
    mlclust::PointMultilevelOptions options;
    options.grid = grid;
    options.threads = threads;
    options.min_clusters = until;
    options.optimise_rounds = rounds;
    options.bounded_drift = bounded;
    options.parallel = algo == "pml";
    if (algo == "hc") options.optimizer = mlclust::PointMultilevelOptions::Optimizer::kNone;
    CurveSink sink(fingerprint != 0);
    mlclust::bench::CancelTimer cancel(cancel_after);
    options.cancel = cancel.flag();
    auto summary = mlclust::RunPointMultilevel(points, options, sink);
    if (cancel_after >= 0) {
      cancel.Report(summary.status(), "RunPointMultilevel");
      return 0;
    }
    if (!summary.ok()) {
      std::fprintf(stderr, "%s\n", summary.status().ToString().c_str());
      return 1;
    }
    if (fingerprint != 0) {
      std::fprintf(stderr, "fingerprint levels=%zu hash=%016" PRIx64 "\n", sink.counts.size(),
                   sink.hash());
    }
    steps = summary->levels;
    used_grid = summary->grid;
    start_clusters = summary->start_clusters;
    if (!curve.empty()) {
      std::FILE* out = std::fopen(curve.c_str(), "w");
      if (out == nullptr) return 1;
      std::fprintf(out, "clusters,energy\n");
      for (size_t l = 0; l < sink.counts.size(); ++l) {
        std::fprintf(out, "%u,%.10g\n", sink.counts[l], sink.energies[l]);
      }
      std::fclose(out);
    }
    for (size_t l = 0; l < sink.counts.size(); ++l) {
      if (sink.counts[l] <= k) {
        energy = sink.energies[l];
        break;
      }
    }
  }
  const double seconds = watch.Seconds();
  std::printf("%s,%llu,%u,%u,%u,%u,%d,%.3f,%.3f,%llu,%.10g,%u\n", algo.c_str(),
              static_cast<unsigned long long>(m), d, blobs, k, used_grid, threads, seconds,
              init_seconds, static_cast<unsigned long long>(steps), energy, start_clusters);
  return 0;
}
