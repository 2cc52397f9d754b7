// Which level a preview draws (server/preview.h): the last with exactly K clusters, else
// the first with fewer, else (K = 0) the last; the labels are those of that level.
#include <gtest/gtest.h>

#include <vector>

#include "server/preview.h"

namespace mlclust::server {
namespace {

// Four elements, start {0, 1, 2, 3} (4 clusters); the levels below, each one move.
struct Move {
  uint32_t cluster_count;
  uint32_t element, to, from;
};

PreviewLevelSink Follow(uint32_t wanted, const std::vector<Move>& moves,
                        std::vector<ClusterId> start = {ClusterId(0), ClusterId(1), ClusterId(2),
                                                        ClusterId(3)}) {
  PreviewLevelSink sink(wanted);
  EXPECT_TRUE(sink.OnStart(start, static_cast<uint32_t>(start.size()), 0.0).ok());
  uint32_t number = 0;
  for (const Move& move : moves) {
    LevelMoves level;
    level.level = ++number;
    level.cluster_count = move.cluster_count;
    level.element = {&move.element, 1};
    level.to_cluster = {&move.to, 1};
    level.from_cluster = {&move.from, 1};
    EXPECT_TRUE(sink.OnLevel(level).ok());
  }
  return sink;
}

std::vector<uint32_t> Values(std::span<const ClusterId> labels) {
  std::vector<uint32_t> out;
  for (ClusterId label : labels) out.push_back(label.value());
  return out;
}

// 4 -> 3 -> 2 -> 2 clusters: element 1 joins 0, then 3 joins 2, then 2 moves to 0.
const std::vector<Move> kMerges = {{3, 1, 0, 1}, {2, 3, 2, 3}, {2, 2, 0, 2}};

// The sink holds level `level`, of `count` clusters, with these labels.
void ExpectHeld(const PreviewLevelSink& sink, uint32_t count, uint32_t level,
                const std::vector<uint32_t>& labels) {
  EXPECT_EQ(sink.cluster_count(), count);
  EXPECT_EQ(sink.level(), level);
  EXPECT_EQ(Values(sink.labels()), labels);
}

TEST(PreviewLevelSinkTest, ExactCountIsKept) { ExpectHeld(Follow(3, kMerges), 3, 1, {0, 0, 2, 3}); }

TEST(PreviewLevelSinkTest, LastLevelWithTheExactCountWins) {
  // Two levels with 2 clusters: the second is drawn (a single-level algorithm's result
  // follows its seeding at the same K).
  ExpectHeld(Follow(2, kMerges), 2, 3, {0, 0, 0, 2});
}

TEST(PreviewLevelSinkTest, SkippedCountTakesTheFirstWithFewer) {
  // 4 -> 2 -> 1 (PML may skip 3).
  ExpectHeld(Follow(3, {{2, 1, 0, 1}, {1, 2, 0, 2}}), 2, 1, {0, 0, 2, 3});
}

TEST(PreviewLevelSinkTest, ZeroMeansTheLastLevelAndTheStartMayBeBelow) {
  const PreviewLevelSink last = Follow(0, kMerges);
  EXPECT_EQ(last.level(), 3u);
  EXPECT_EQ(last.cluster_count(), 2u);
  // Asking for 10 when the start has 4: the start is the first level with fewer.
  const PreviewLevelSink start = Follow(10, kMerges);
  EXPECT_EQ(start.level(), 0u);
  EXPECT_EQ(start.cluster_count(), 4u);
  EXPECT_EQ(Values(start.labels()), (std::vector<uint32_t>{0, 1, 2, 3}));
}

TEST(PreviewLevelSinkTest, MoveOfAnElementOutOfRangeIsAnError) {
  PreviewLevelSink sink(0);
  const std::vector<ClusterId> start = {ClusterId(0), ClusterId(1)};
  ASSERT_TRUE(sink.OnStart(start, 2, 0.0).ok());
  const uint32_t element = 7, to = 0, from = 1;
  LevelMoves level;
  level.cluster_count = 1;
  level.element = {&element, 1};
  level.to_cluster = {&to, 1};
  level.from_cluster = {&from, 1};
  EXPECT_EQ(sink.OnLevel(level).code(), absl::StatusCode::kInternal);
}

}  // namespace
}  // namespace mlclust::server
