// The bounded job queue: refuses at once when full, lanes, removal, drain, the full state
// readiness follows.
#include "server/job_queue.h"

#include <gtest/gtest.h>

#include <string>

namespace mlclust::server {
namespace {

using Queue = BoundedJobQueue<std::string>;

std::shared_ptr<std::string> Job(const char* name) { return std::make_shared<std::string>(name); }

TEST(BoundedJobQueueTest, RefusesAtOnceWhenFullAcrossLanes) {
  Queue queue(3);
  EXPECT_EQ(*queue.Push(Job("a"), 0), 0u);
  EXPECT_EQ(*queue.Push(Job("b"), 1), 0u);  // jobs ahead count in the job's own lane
  EXPECT_EQ(*queue.Push(Job("c"), 0), 1u);
  absl::StatusOr<size_t> full = queue.Push(Job("d"), 1);
  EXPECT_EQ(full.status().code(), absl::StatusCode::kResourceExhausted);
  EXPECT_EQ(queue.size(), 3u);
}

TEST(BoundedJobQueueTest, WorkersTakeTheOldestJobOfTheirLanes) {
  Queue queue(8);
  queue.Push(Job("gl-1"), 0);
  queue.Push(Job("cpu-1"), 1);
  queue.Push(Job("gl-2"), 0);
  queue.Push(Job("cpu-2"), 1);
  EXPECT_EQ(*queue.Pop(1u << 1), "cpu-1");
  EXPECT_EQ(*queue.Pop(1u << 0), "gl-1");
  EXPECT_EQ(*queue.Pop(), "gl-2");  // all lanes: the oldest
  EXPECT_EQ(*queue.Pop(1u << 1), "cpu-2");
}

TEST(BoundedJobQueueTest, PositionsRemoveAndDrain) {
  Queue queue(8);
  auto a = Job("a"), b = Job("b"), c = Job("c");
  queue.Push(a, 0);
  queue.Push(b, 1);
  queue.Push(c, 0);
  std::vector<std::pair<std::string, size_t>> seen;
  queue.ForEachWaiting([&](const std::string& job, size_t ahead) { seen.push_back({job, ahead}); });
  EXPECT_EQ(seen, (std::vector<std::pair<std::string, size_t>>{{"a", 0}, {"b", 0}, {"c", 1}}));
  EXPECT_TRUE(queue.Remove(a.get()));
  EXPECT_FALSE(queue.Remove(a.get()));
  std::vector<std::shared_ptr<std::string>> taken = queue.StopAndTakeAll();
  ASSERT_EQ(taken.size(), 2u);
  EXPECT_EQ(*taken[0], "b");
  EXPECT_EQ(*taken[1], "c");
  EXPECT_EQ(queue.Pop(), nullptr);  // stopped and empty: at once
  EXPECT_EQ(queue.Push(Job("late"), 0).status().code(), absl::StatusCode::kFailedPrecondition);
}

// SetOnFull: told once when the queue fills and once when it has room again, by Pop,
// Remove and the drain alike (the server's readiness follows it).
TEST(BoundedJobQueueTest, TellsWhenItIsFullAndWhenItHasRoomAgain) {
  Queue queue(2);
  std::vector<bool> told;
  queue.SetOnFull([&](bool full) { told.push_back(full); });
  auto a = Job("a"), b = Job("b");
  ASSERT_TRUE(queue.Push(a, 0).ok());
  EXPECT_TRUE(told.empty());
  ASSERT_TRUE(queue.Push(b, 0).ok());
  EXPECT_EQ(told, (std::vector<bool>{true}));
  EXPECT_FALSE(queue.Push(Job("refused"), 0).ok());
  EXPECT_EQ(told, (std::vector<bool>{true}));  // a refusal changes nothing
  EXPECT_EQ(*queue.Pop(), "a");
  EXPECT_EQ(told, (std::vector<bool>{true, false}));
  ASSERT_TRUE(queue.Push(Job("c"), 0).ok());
  EXPECT_TRUE(queue.Remove(b.get()));
  ASSERT_TRUE(queue.Push(Job("d"), 0).ok());
  EXPECT_EQ(told, (std::vector<bool>{true, false, true, false, true}));
  EXPECT_EQ(queue.StopAndTakeAll().size(), 2u);
  EXPECT_EQ(told, (std::vector<bool>{true, false, true, false, true, false}));
}

}  // namespace
}  // namespace mlclust::server
