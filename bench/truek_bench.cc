// The true-number-of-clusters experiment of the dissertation's Fig. 6.15: K Gaussian blobs
// in 3-D, sigma 1, exactly `per-blob` points each, centres uniform in [-25, 25]^3; the ML
// hierarchy of each data set (RunPointMultilevel, LN k-means optimiser, default voxel start)
// and the textbook spherical-Gaussian BIC of every level (core/model_selection.h).
//
//   truek_bench [--ks 10,25,50,100,150,200,250] [--sets 10] [--per-blob 500] [--seed S]
//               [--algo ml|hc|pml] [--write-npy DIR]
//
// Prints one CSV row per data set:
//   algo,K,set,m,seconds,levels,best_k,first_decrease_k
// seconds: the hierarchy and the BIC of all its levels. --write-npy DIR also writes each data
// set to DIR/truek_K<K>_s<set>.npy, for the Ward + BIC peer (bench/peers/points_peers.py).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "bench/bench_util.h"
#include "core/base/random.h"
#include "core/cluster/point_clustering.h"
#include "core/hierarchy/model_selection.h"
#include "core/io/points_io.h"

int main(int argc, char** argv) {
  mlclust::bench::Args args(argc, argv,
                            "usage: truek_bench [--ks 10,25,...] [--sets N] [--per-blob N] "
                            "[--seed S] [--algo ml|hc|pml] [--write-npy DIR]");
  const std::vector<uint32_t> ks = args.GetList<uint32_t>("ks", "10,25,50,100,150,200,250");
  const uint32_t sets = args.Get<uint32_t>("sets", 10);
  const uint32_t per_blob = args.Get<uint32_t>("per-blob", 500);
  const uint64_t seed = args.Get<uint64_t>("seed", 1);
  const std::string algo = args.Get<std::string>("algo", "ml");
  const std::string npy_dir = args.Get<std::string>("write-npy", "");
  if (!args.Done()) return 2;
  if (per_blob == 0 || std::find(ks.begin(), ks.end(), 0u) != ks.end() ||
      (algo != "ml" && algo != "hc" && algo != "pml")) {
    std::fprintf(stderr, "--ks and --per-blob must be > 0 and --algo one of ml, hc, pml\n");
    return 2;
  }
  std::printf("algo,K,set,m,seconds,levels,best_k,first_decrease_k\n");
  for (uint32_t k : ks) {
    for (uint32_t set = 0; set < sets; ++set) {
      mlclust::Random random(seed * 1000003 + k * 1009 + set);
      std::vector<double> centres(size_t{k} * 3);
      for (double& c : centres) c = -25 + 50 * random.Unit();
      mlclust::PointSet points;
      points.dims = 3;
      points.values.resize(size_t{k} * per_blob * 3);
      size_t at = 0;
      for (uint32_t b = 0; b < k; ++b) {
        for (uint32_t p = 0; p < per_blob; ++p) {
          for (uint32_t j = 0; j < 3; ++j) {
            const double u = std::max(random.Unit(), 1e-300), v = random.Unit();
            points.values[at++] = static_cast<float>(
                centres[b * 3 + j] + std::sqrt(-2 * std::log(u)) * std::cos(6.283185307179586 * v));
          }
        }
      }
      if (!npy_dir.empty()) {
        const std::string path = absl::StrCat(npy_dir, "/truek_K", k, "_s", set, ".npy");
        if (absl::Status s = mlclust::WritePointsNpy(path, points); !s.ok()) {
          std::fprintf(stderr, "%s\n", s.ToString().c_str());
          return 1;
        }
      }
      const absl::Time start = absl::Now();
      mlclust::PointMultilevelOptions options;
      options.parallel = algo == "pml";
      if (algo == "hc") options.optimizer = mlclust::PointMultilevelOptions::Optimizer::kNone;
      mlclust::BicLevelRecorder recorder;
      const mlclust::PointMultilevelSummary summary =
          mlclust::bench::ValueOrDie(mlclust::RunPointMultilevel(points, options, recorder));
      const mlclust::BicChoice choice = mlclust::bench::ValueOrDie(
          mlclust::ChooseByBic(recorder.levels(), recorder.num_points(), 3));
      const double seconds = absl::ToDoubleSeconds(absl::Now() - start);
      std::printf("%s,%u,%u,%zu,%.3f,%u,%u,%u\n", algo.c_str(), k, set, points.num_points(),
                  seconds, summary.levels, choice.best_k, choice.first_decrease_k);
      std::fflush(stdout);
    }
  }
  return 0;
}
