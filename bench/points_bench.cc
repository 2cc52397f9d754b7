// Times point clustering on synthetic Gaussian blobs (or a raw float32 file).
//   points_bench --algo ml|pml|hc|lnkmeans [--m M] [--d D] [--blobs K] [--k K]
//                [--grid A] [--threads T] [--seed S] [--raw FILE --dims D]
// Prints one CSV row: algo,m,d,blobs,k,grid,threads,seconds,levels_or_iterations,energy
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>

#include "absl/strings/numbers.h"
#include "absl/time/clock.h"
#include "bench/curve_sink.h"
#include "core/point_clustering.h"
#include "core/random.h"

namespace {

using CurveSink = mlclust::bench::CurveSink;

}  // namespace

int main(int argc, char** argv) {
  std::string algo = "ml", raw;
  uint64_t m = 100000, seed = 1;
  uint32_t d = 3, blobs = 100, k = 1000, grid = 0, dims = 0;
  int threads = 0;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string arg = argv[i], value = argv[i + 1];
    bool ok = true;
    if (arg == "--algo")
      algo = value;
    else if (arg == "--m")
      ok = absl::SimpleAtoi(value, &m);
    else if (arg == "--d")
      ok = absl::SimpleAtoi(value, &d);
    else if (arg == "--blobs")
      ok = absl::SimpleAtoi(value, &blobs);
    else if (arg == "--k")
      ok = absl::SimpleAtoi(value, &k);
    else if (arg == "--grid")
      ok = absl::SimpleAtoi(value, &grid);
    else if (arg == "--threads")
      ok = absl::SimpleAtoi(value, &threads);
    else if (arg == "--seed")
      ok = absl::SimpleAtoi(value, &seed);
    else if (arg == "--raw")
      raw = value;
    else if (arg == "--dims")
      ok = absl::SimpleAtoi(value, &dims);
    else
      ok = false;
    if (!ok) {
      std::fprintf(stderr, "bad option %s %s\n", arg.c_str(), value.c_str());
      return 2;
    }
  }
  mlclust::PointSet points;
  if (!raw.empty()) {
    std::ifstream in(raw, std::ios::binary);
    in.seekg(0, std::ios::end);
    points.values.resize(static_cast<size_t>(in.tellg()) / 4);
    in.seekg(0);
    in.read(reinterpret_cast<char*>(points.values.data()), points.values.size() * 4);
    points.dims = dims;
    m = points.num_points();
    d = dims;
  } else {
    // Blobs: centres uniform in [-25, 25]^d, sigma 1.
    mlclust::Random random(seed);
    points.dims = d;
    std::vector<double> centres(size_t{blobs} * d);
    for (double& c : centres) c = -25 + 50 * random.Unit();
    points.values.resize(m * d);
    for (uint64_t i = 0; i < m; ++i) {
      const uint64_t b = random.Below(blobs);
      for (uint32_t j = 0; j < d; ++j) {
        const double u = std::max(random.Unit(), 1e-300), v = random.Unit();
        points.values[i * d + j] = static_cast<float>(
            centres[b * d + j] + std::sqrt(-2 * std::log(u)) * std::cos(6.283185307179586 * v));
      }
    }
  }
  const absl::Time start = absl::Now();
  uint64_t steps = 0;
  double energy = 0;
  uint32_t used_grid = grid;
  if (algo == "lnkmeans") {
    auto labels = mlclust::SeedPointClusters(points, k, true, seed, threads);
    if (!labels.ok()) return 1;
    mlclust::LnKmeansOptions options;
    options.threads = threads;
    auto result = mlclust::RunLnKmeans(points, *labels, options);
    if (!result.ok()) return 1;
    steps = result->iterations;
    energy = result->energy;
  } else {
    mlclust::PointMultilevelOptions options;
    options.grid = grid;
    options.threads = threads;
    options.parallel = algo == "pml";
    if (algo == "hc") options.optimizer = mlclust::PointMultilevelOptions::Optimizer::kNone;
    CurveSink sink;
    auto summary = mlclust::RunPointMultilevel(points, options, sink);
    if (!summary.ok()) {
      std::fprintf(stderr, "%s\n", summary.status().ToString().c_str());
      return 1;
    }
    steps = summary->levels;
    used_grid = summary->grid;
    for (size_t l = 0; l < sink.counts.size(); ++l) {
      if (sink.counts[l] <= k) {
        energy = sink.energies[l];
        break;
      }
    }
    std::fprintf(stderr, "start clusters %u\n", summary->start_clusters);
  }
  const double seconds = absl::ToDoubleSeconds(absl::Now() - start);
  std::printf("%s,%llu,%u,%u,%u,%u,%d,%.3f,%llu,%.10g\n", algo.c_str(),
              static_cast<unsigned long long>(m), d, blobs, k, used_grid, threads, seconds,
              static_cast<unsigned long long>(steps), energy);
  return 0;
}
