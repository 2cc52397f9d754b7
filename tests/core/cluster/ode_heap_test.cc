#include "core/cluster/detail/ode_heap.h"

#include <gtest/gtest.h>

#include <limits>
#include <vector>

namespace mlclust::detail {
namespace {

TEST(CheaperDualEdgeTest, CheaperWinsAndEqualCostsGoToTheLargerId) {
  EXPECT_TRUE(CheaperDualEdge(1.0, 3, 2.0, 7));
  EXPECT_FALSE(CheaperDualEdge(2.0, 9, 1.0, 7));
  EXPECT_TRUE(CheaperDualEdge(1.0, 9, 1.0, 7));
  EXPECT_FALSE(CheaperDualEdge(1.0, 3, 1.0, 7));
  // The first candidate is taken even at an infinite cost.
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_TRUE(CheaperDualEdge(inf, 3, inf, kNoCluster));
}

TEST(OdeHeapTest, PopsCheapestFirstSmallerIdOnTiesAndSkipsStaleAndDeadEntries) {
  OdeHeap heap(6);
  std::vector<bool> alive(6, true);
  auto is_alive = [&](uint32_t c) { return static_cast<bool>(alive[c]); };
  heap.Set(0, 1, 5.0);
  heap.Set(1, 0, 5.0);
  heap.Set(2, 3, 1.0);
  heap.Set(3, 2, 2.0);
  heap.Set(4, 5, 0.5);
  heap.Set(5, kNoCluster, 0.1);  // no partner: not queued
  EXPECT_EQ(heap.queued(), 5u);
  heap.Set(2, 3, 7.0);  // 2's entry at 1.0 is stale now
  alive[4] = false;     // 4's entry is dead
  EXPECT_EQ(heap.partner(2), 3u);
  EXPECT_EQ(heap.cost(2), 7.0);
  EXPECT_EQ(heap.PopCheapest(is_alive), 3u);
  EXPECT_EQ(heap.PopCheapest(is_alive), 0u);  // 0 and 1 at 5.0: the smaller id first
  EXPECT_EQ(heap.PopCheapest(is_alive), 1u);
  heap.Invalidate(2);
  EXPECT_EQ(heap.PopCheapest(is_alive), kNoCluster);
}

TEST(OdeHeapTest, SetWithoutQueueAndAssignQueueNothingUntilRebuilt) {
  OdeHeap heap(3);
  auto all = [](uint32_t) { return true; };
  heap.Set(0, 1, 3.0, /*queue=*/false);
  heap.Assign(1, 0, 3.0);
  heap.Assign(2, 1, 1.0);
  EXPECT_EQ(heap.queued(), 0u);
  EXPECT_EQ(heap.PopCheapest(all), kNoCluster);
  heap.Rebuild(all);
  EXPECT_EQ(heap.queued(), 3u);
  EXPECT_EQ(heap.PopCheapest(all), 2u);
  EXPECT_EQ(heap.PopCheapest(all), 0u);
}

TEST(OdeHeapTest, CompactsOnlyWhenStaleEntriesOutnumberTheLiveClustersFourToOne) {
  OdeHeap heap(2);
  auto all = [](uint32_t) { return true; };
  for (int i = 0; i < 4104; ++i) heap.Set(i % 2, 1 - i % 2, 1.0 + i);
  EXPECT_EQ(heap.queued(), 4104u);
  heap.MaybeCompact(2, all);  // 4104 <= 4 * 2 + 4096
  EXPECT_EQ(heap.queued(), 4104u);
  heap.Set(0, 1, 0.5);
  heap.MaybeCompact(2, all);
  EXPECT_EQ(heap.queued(), 2u);
  EXPECT_EQ(heap.PopCheapest(all), 0u);
  EXPECT_EQ(heap.cost(1), 4104.0);
}

}  // namespace
}  // namespace mlclust::detail
