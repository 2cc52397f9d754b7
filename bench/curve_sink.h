// A LevelSink for benchmarks: keeps each level's cluster count and energy, not the triplets.
#ifndef MLCLUST_BENCH_CURVE_SINK_H_
#define MLCLUST_BENCH_CURVE_SINK_H_

#include <vector>

#include "core/hierarchy/hierarchy.h"

namespace mlclust::bench {

class CurveSink : public LevelSink {
 public:
  absl::Status OnStart(std::span<const ClusterId>, uint32_t count, double energy) override {
    counts.assign(1, count);
    energies.assign(1, energy);
    return absl::OkStatus();
  }
  absl::Status OnLevel(const LevelMoves& level) override {
    counts.push_back(level.cluster_count);
    energies.push_back(level.energy);
    return absl::OkStatus();
  }
  std::vector<uint32_t> counts;
  std::vector<double> energies;
};

}  // namespace mlclust::bench

#endif  // MLCLUST_BENCH_CURVE_SINK_H_
