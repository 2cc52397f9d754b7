// Where the BIC of an ML point hierarchy chooses, read three ways (section 6.6): its
// maximum; its first decrease from few clusters to many (ChooseByBic's first_decrease, the
// server's rule); and its first decrease in the agglomerative direction, from the
// voxel-grid start towards one cluster ("the ML algorithm stops when the BIC value starts
// to decrease", l. 2798): the first level whose BIC is above that of the next level.
//   bic_direction FILE.npy [--grid A]
// Prints "start_clusters,bic_max_k,first_decrease_few_to_many_k,first_decrease_agglomerative_k".
#include <cmath>
#include <cstdio>
#include <string>

#include "absl/strings/numbers.h"
#include "core/cluster/point_clustering.h"
#include "core/hierarchy/model_selection.h"
#include "core/io/points_io.h"

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: bic_direction FILE [--grid A]\n");
    return 2;
  }
  mlclust::PointMultilevelOptions options;
  if (argc == 4 && std::string(argv[2]) == "--grid" && !absl::SimpleAtoi(argv[3], &options.grid)) {
    std::fprintf(stderr, "bad --grid\n");
    return 2;
  }
  absl::StatusOr<mlclust::PointSet> points = mlclust::ReadPointsFile(argv[1]);
  if (!points.ok()) {
    std::fprintf(stderr, "%s\n", points.status().ToString().c_str());
    return 1;
  }
  mlclust::BicLevelRecorder recorder;
  absl::StatusOr<mlclust::PointMultilevelSummary> summary =
      mlclust::RunPointMultilevel(*points, options, recorder);
  if (!summary.ok()) {
    std::fprintf(stderr, "%s\n", summary.status().ToString().c_str());
    return 1;
  }
  absl::StatusOr<mlclust::BicChoice> choice =
      mlclust::ChooseByBic(recorder.levels(), recorder.num_points(), points->dims);
  if (!choice.ok()) {
    std::fprintf(stderr, "%s\n", choice.status().ToString().c_str());
    return 1;
  }
  const auto& levels = recorder.levels();
  uint32_t agglomerative = levels.back().clusters;
  for (size_t l = 0; l + 1 < choice->bic.size(); ++l) {
    if (std::isfinite(choice->bic[l]) && choice->bic[l] > choice->bic[l + 1]) {
      agglomerative = levels[l].clusters;
      break;
    }
  }
  std::printf("%u,%u,%u,%u\n", levels.front().clusters, choice->best_k, choice->first_decrease_k,
              agglomerative);
  return 0;
}
