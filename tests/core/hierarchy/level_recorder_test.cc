#include "core/hierarchy/level_recorder.h"

#include <gtest/gtest.h>

#include <vector>

#include "tests/fixtures/recording_sink.h"

namespace mlclust {
namespace {

using Collect = testing::LevelListSink;

// Four elements in clusters {0, 0, 1, 2}; a cluster's "energy" is its element count.
TEST(LevelRecorderTest, SquashesMovesKeepsTheFirstOriginAndAddsEnergyChanges) {
  std::vector<uint32_t> label = {0, 0, 1, 2};
  auto energy_of = [&](uint32_t c) {
    double n = 0;
    for (uint32_t l : label) n += l == c;
    return n;
  };
  auto label_of = [&](uint32_t e) { return label[e]; };
  auto id_of = [](uint32_t e) { return 10 + e; };
  auto move = [&](LevelRecorder& r, uint32_t e, uint32_t to) {
    r.Touch(label[e], energy_of);
    r.Touch(to, energy_of);
    r.RecordMove(e, label[e]);
    label[e] = to;
  };
  LevelRecorder recorder(4, 3);
  recorder.Reset(100);
  Collect sink;
  move(recorder, 2, 0);  // 2: 1 -> 0
  move(recorder, 3, 1);  // 3: 2 -> 1
  move(recorder, 3, 2);  // 3: 1 -> 2, back where it was: no triplet
  move(recorder, 1, 2);  // 1: 0 -> 2
  move(recorder, 1, 1);  // 1: 2 -> 1, its triplet names 0 as the old cluster
  EXPECT_EQ(std::vector<uint32_t>(recorder.affected().begin(), recorder.affected().end()),
            (std::vector<uint32_t>{1, 0, 2}));
  recorder.Squash(energy_of, label_of, id_of);
  EXPECT_EQ(recorder.affected().size(), 3u);  // still listed until Emit
  ASSERT_TRUE(recorder.Emit(sink, 1, 3).ok());
  EXPECT_TRUE(recorder.affected().empty());
  ASSERT_EQ(sink.element.size(), 1u);
  EXPECT_EQ(sink.triplets(0), (std::vector<std::vector<uint32_t>>{{12, 0, 1}, {11, 1, 0}}));
  EXPECT_EQ(sink.levels[0], 1u);
  EXPECT_EQ(sink.counts[0], 3u);
  EXPECT_EQ(sink.energies[0], 100.0);  // the cluster sizes end as they started
  EXPECT_EQ(recorder.moves(), 2u);

  // The next level starts clean: element 2 moves again, from its cluster at level 1.
  move(recorder, 2, 2);
  recorder.Squash(energy_of, label_of, id_of);
  sink.status = absl::CancelledError("stop");
  EXPECT_EQ(recorder.Emit(sink, 2, 3).code(), absl::StatusCode::kCancelled);
  EXPECT_EQ(sink.triplets(1), (std::vector<std::vector<uint32_t>>{{12, 2, 0}}));
  EXPECT_EQ(sink.energies[1], 100.0);
  EXPECT_EQ(recorder.moves(), 3u);
}

TEST(LevelRecorderTest, EnergyIsTheRunningSumOfTheTouchedClustersChanges) {
  std::vector<double> energy = {1.0, 2.0, 3.0};
  auto energy_of = [&](uint32_t c) { return energy[c]; };
  LevelRecorder recorder(1, 3);
  recorder.Reset(6.0);
  recorder.Touch(0, energy_of);
  recorder.Touch(2, energy_of);
  energy[0] = 0.5;
  energy[2] = 4.0;
  energy[1] = 100.0;  // not touched: not counted
  recorder.Squash(
      energy_of, [](uint32_t) { return 0u; }, [](uint32_t e) { return e; });
  EXPECT_DOUBLE_EQ(recorder.energy(), 6.5);
}

}  // namespace
}  // namespace mlclust
