// Times X-means (Alg. 2.5) or bisecting k-means (Alg. 2.7) on a point file (.npy, .csv, or
// raw float32 with --dims; bench/points_data.py writes the blobs, which
// bench/experiments/sklearn_divisive.py reads too).
//   divisive_bench --algo bisecting|xmeans --input FILE [--dims D] [--k K]
//                  [--split size|energy] [--trials L] [--init random|kmeans++]
//                  [--kmin K] [--kmax K] [--lookahead L] [--seed S] [--threads T]
// --k is the bisecting k; --kmin/--kmax X-means' range (kmax 0: the number of points).
// Prints one JSON object: algo, options, seconds, clusters, energy (the sum of squared
// distances to the cluster means, in double, recomputed from the labels), and for X-means
// the rounds (clusters, BIC).
#include <cstdio>
#include <string>

#include "absl/time/clock.h"
#include "bench/bench_util.h"
#include "core/cluster/bisecting_kmeans.h"
#include "core/cluster/point_clustering.h"
#include "core/cluster/xmeans.h"

int main(int argc, char** argv) {
  mlclust::bench::Args args(argc, argv,
                            "usage: divisive_bench --algo bisecting|xmeans --input FILE [--dims D] "
                            "[--k K] [--split size|energy] [--trials L] [--init random|kmeans++] "
                            "[--kmin K] [--kmax K] [--seed S] [--threads T]");
  const std::string algo = args.Get<std::string>("algo", "bisecting");
  const std::string input = args.Get<std::string>("input", "");
  const uint32_t dims = args.Get<uint32_t>("dims", 0);
  const uint32_t k = args.Get<uint32_t>("k", 100);
  const std::string split = args.Get<std::string>("split", "size");
  const uint32_t trials = args.Get<uint32_t>("trials", 1);
  const std::string init = args.Get<std::string>("init", "");
  const uint32_t kmin = args.Get<uint32_t>("kmin", 1);
  const uint32_t kmax = args.Get<uint32_t>("kmax", 0);
  const uint32_t lookahead = args.Get<uint32_t>("lookahead", mlclust::XmeansOptions{}.lookahead);
  const uint64_t seed = args.Get<uint64_t>("seed", 1);
  const int threads = args.Get<int>("threads", 0);
  if (!args.Done()) return 2;
  if (input.empty()) {
    std::fprintf(stderr, "--input FILE is required\n");
    return 2;
  }
  const mlclust::PointSet points = mlclust::bench::ReadPointsOrDie(input, dims);
  const auto kmeans_init = [&](mlclust::KmeansOptions::Init fallback) {
    if (init == "random") return mlclust::KmeansOptions::Init::kRandom;
    if (init == "kmeans++") return mlclust::KmeansOptions::Init::kKmeansPlusPlus;
    return fallback;
  };
  const absl::Time start = absl::Now();
  if (algo == "bisecting") {
    mlclust::BisectingKmeansOptions options;
    options.clusters = k;
    options.split = split == "energy" ? mlclust::BisectingKmeansOptions::SplitChoice::kLargestEnergy
                                      : mlclust::BisectingKmeansOptions::SplitChoice::kLargestSize;
    options.trials = trials;
    options.init = kmeans_init(mlclust::KmeansOptions::Init::kRandom);
    options.seed = seed;
    options.threads = threads;
    absl::StatusOr<mlclust::BisectingKmeansResult> result =
        mlclust::RunBisectingKmeans(points, options);
    const double seconds = absl::ToDoubleSeconds(absl::Now() - start);
    if (!result.ok()) {
      std::fprintf(stderr, "%s\n", result.status().ToString().c_str());
      return 1;
    }
    std::printf(
        "{\"algo\": \"mlclust bisecting\", \"split\": \"%s\", \"trials\": %u, \"init\": \"%s\", "
        "\"seed\": %lu, \"threads\": %d, \"m\": %zu, \"seconds\": %.4f, \"clusters\": %u, "
        "\"energy\": %.10g}\n",
        split.c_str(), trials,
        options.init == mlclust::KmeansOptions::Init::kRandom ? "random" : "kmeans++",
        static_cast<unsigned long>(seed), threads, points.num_points(), seconds, k,
        mlclust::PointEnergy(points, result->labels));
  } else if (algo == "xmeans") {
    mlclust::XmeansOptions options;
    options.min_clusters = kmin;
    options.max_clusters = kmax;
    options.split_trials = trials;
    options.lookahead = lookahead;
    options.init = kmeans_init(mlclust::KmeansOptions::Init::kKmeansPlusPlus);
    options.seed = seed;
    options.threads = threads;
    absl::StatusOr<mlclust::XmeansResult> result = mlclust::RunXmeans(points, options);
    const double seconds = absl::ToDoubleSeconds(absl::Now() - start);
    if (!result.ok()) {
      std::fprintf(stderr, "%s\n", result.status().ToString().c_str());
      return 1;
    }
    std::string rounds;
    for (const mlclust::XmeansRound& round : result->rounds) {
      if (!rounds.empty()) rounds += ", ";
      char buffer[96];
      std::snprintf(buffer, sizeof buffer, "[%u, %.10g]", round.clusters, round.bic);
      rounds += buffer;
    }
    std::printf(
        "{\"algo\": \"mlclust xmeans\", \"kmin\": %u, \"kmax\": %u, \"trials\": %u, "
        "\"lookahead\": %u, \"seed\": %lu, \"threads\": %d, \"m\": %zu, \"seconds\": %.4f, "
        "\"clusters\": %u, "
        "\"energy\": %.10g, \"bic\": %.10g, \"rounds\": [%s]}\n",
        kmin, kmax, trials, lookahead, static_cast<unsigned long>(seed), threads,
        points.num_points(), seconds, result->clusters,
        mlclust::PointEnergy(points, result->labels), result->bic, rounds.c_str());
  } else {
    std::fprintf(stderr, "--algo must be bisecting or xmeans\n");
    return 2;
  }
  return 0;
}
