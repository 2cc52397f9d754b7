// Where the BIC of an ML point hierarchy chooses, read three ways (section 6.6): its
// maximum; its first decrease from few clusters to many (ChooseByBic's first_decrease, the
// server's rule); and its first decrease in the agglomerative direction, from the
// voxel-grid start towards one cluster ("the ML algorithm stops when the BIC value starts
// to decrease", l. 2798): the first level whose BIC is above that of the next level.
//   bic_direction FILE.npy [--grid A] [--curve CURVE.csv]
// Prints "start_clusters,bic_max_k,first_decrease_few_to_many_k,first_decrease_agglomerative_k";
// --curve writes "clusters,bic" per level (Figs. 6.14/6.16).
#include <cmath>
#include <cstdio>
#include <string>

#include "bench/bench_util.h"
#include "core/cluster/point_clustering.h"
#include "core/hierarchy/model_selection.h"

int main(int argc, char** argv) {
  mlclust::bench::Args args(argc, argv, "usage: bic_direction FILE [--grid A] [--curve CURVE.csv]");
  mlclust::PointMultilevelOptions options;
  const std::string path = args.Positional(0);
  options.grid = args.Get("grid", options.grid);
  const std::string curve_path = args.Get<std::string>("curve", "");
  if (!args.Done()) return 2;
  const mlclust::PointSet points = mlclust::bench::ReadPointsOrDie(path);
  mlclust::BicLevelRecorder recorder;
  mlclust::bench::ValueOrDie(mlclust::RunPointMultilevel(points, options, recorder));
  const mlclust::BicChoice choice = mlclust::bench::ValueOrDie(
      mlclust::ChooseByBic(recorder.levels(), recorder.num_points(), points.dims));
  const auto& levels = recorder.levels();
  if (!curve_path.empty()) {
    FILE* curve = std::fopen(curve_path.c_str(), "w");
    if (curve == nullptr) {
      std::fprintf(stderr, "cannot write %s\n", curve_path.c_str());
      return 1;
    }
    std::fprintf(curve, "clusters,bic\n");
    for (size_t l = 0; l < choice.bic.size(); ++l) {
      if (std::isfinite(choice.bic[l])) {
        std::fprintf(curve, "%u,%.6f\n", levels[l].clusters, choice.bic[l]);
      }
    }
    std::fclose(curve);
  }
  uint32_t agglomerative = levels.back().clusters;
  for (size_t l = 0; l + 1 < choice.bic.size(); ++l) {
    if (std::isfinite(choice.bic[l]) && choice.bic[l] > choice.bic[l + 1]) {
      agglomerative = levels[l].clusters;
      break;
    }
  }
  std::printf("%u,%u,%u,%u\n", levels.front().clusters, choice.best_k, choice.first_decrease_k,
              agglomerative);
  return 0;
}
