// The result store between a job and its call: splitting big events under the message
// limit, the budgets, cutting a slow reader off, cancellation.
#include "server/result_store.h"

#include <gtest/gtest.h>

#include <random>

namespace mlclust::server {
namespace {

// A batch of `levels` levels with `triplets_per_level` triplets each, large ids so
// varints take several bytes.
v1::JobEvent MakeBatch(uint32_t first_level, int levels, int triplets_per_level,
                       uint32_t seed = 1) {
  std::mt19937 random(seed);
  v1::JobEvent event;
  v1::LevelBatch* batch = event.mutable_levels();
  batch->set_first_level(first_level);
  for (int l = 0; l < levels; ++l) {
    batch->add_cluster_count(1000000 - l);
    batch->add_energy(0.5 * l + 1);
    batch->add_source_level(7 + l);
    for (int t = 0; t < triplets_per_level; ++t) {
      batch->add_element(random() % 3000000);
      batch->add_to_cluster(random() % 3000000);
      batch->add_from_cluster(random() % 3000000);
    }
    batch->add_triplet_end(static_cast<uint32_t>(batch->element_size()));
  }
  return event;
}

struct Level {
  uint32_t number, cluster_count, source;
  double energy;
  std::vector<uint32_t> element, to, from;
  bool operator==(const Level&) const = default;
};

// Joins pieces the way a client must (last_level_continues), checking the contract.
std::vector<Level> Join(const std::vector<v1::JobEvent>& pieces) {
  std::vector<Level> levels;
  bool continuing = false;
  for (const v1::JobEvent& piece : pieces) {
    const v1::LevelBatch& b = piece.levels();
    uint32_t begin = 0;
    for (int i = 0; i < b.cluster_count_size(); ++i) {
      const uint32_t number = b.first_level() + i;
      if (i == 0 && continuing) {
        EXPECT_EQ(levels.back().number, number);
        EXPECT_EQ(levels.back().cluster_count, b.cluster_count(0));
      } else {
        if (!levels.empty()) EXPECT_EQ(levels.back().number + 1, number);
        levels.push_back({number, b.cluster_count(i), b.source_level(i), b.energy(i), {}, {}, {}});
      }
      Level& level = levels.back();
      for (uint32_t t = begin; t < b.triplet_end(i); ++t) {
        level.element.push_back(b.element(t));
        level.to.push_back(b.to_cluster(t));
        level.from.push_back(b.from_cluster(t));
      }
      begin = b.triplet_end(i);
    }
    continuing = b.last_level_continues();
  }
  EXPECT_FALSE(continuing) << "the last piece says its level continues";
  return levels;
}

TEST(SplitLargeEventTest, SmallEventsComeBackWhole) {
  const v1::JobEvent batch = MakeBatch(3, 4, 10);
  const std::vector<v1::JobEvent> pieces = SplitLargeEvent(batch, 1 << 20);
  ASSERT_EQ(pieces.size(), 1u);
  EXPECT_EQ(pieces[0].SerializeAsString(), batch.SerializeAsString());
  v1::JobEvent progress;
  progress.mutable_progress()->set_message(std::string(5000, 'x'));
  EXPECT_EQ(SplitLargeEvent(progress, 1024).size(), 1u);  // only levels and snapshots split
}

TEST(SplitLargeEventTest, OneHugeLevelContinuesAcrossPiecesUnderTheLimit) {
  const v1::JobEvent batch = MakeBatch(1, 1, 200000);  // ~2 MB in one level
  const size_t limit = 200 << 10;
  ASSERT_GT(batch.ByteSizeLong(), 8 * limit);
  const std::vector<v1::JobEvent> pieces = SplitLargeEvent(batch, limit);
  EXPECT_GT(pieces.size(), 8u);
  for (size_t i = 0; i < pieces.size(); ++i) {
    EXPECT_LE(pieces[i].ByteSizeLong(), limit) << "piece " << i;
    EXPECT_EQ(pieces[i].levels().first_level(), 1u);
    EXPECT_EQ(pieces[i].levels().last_level_continues(), i + 1 < pieces.size());
  }
  EXPECT_EQ(Join(pieces), Join({batch}));
}

TEST(SplitLargeEventTest, ManyLevelsOfAllSizesRejoinExactly) {
  v1::JobEvent batch = MakeBatch(10, 0, 0);
  // Levels of 0 to 30000 triplets, so cuts fall between and inside levels.
  for (int l = 0, sizes[] = {0, 5, 30000, 1, 0, 12000, 7, 25000, 3}; l < 9; ++l) {
    const v1::JobEvent one = MakeBatch(0, 1, sizes[l], l + 2);
    v1::LevelBatch* b = batch.mutable_levels();
    b->add_cluster_count(100 - l);
    b->add_energy(l);
    b->add_source_level(l);
    b->mutable_element()->MergeFrom(one.levels().element());
    b->mutable_to_cluster()->MergeFrom(one.levels().to_cluster());
    b->mutable_from_cluster()->MergeFrom(one.levels().from_cluster());
    b->add_triplet_end(static_cast<uint32_t>(b->element_size()));
  }
  for (size_t limit : {size_t{2048}, size_t{50000}, size_t{300000}}) {
    const std::vector<v1::JobEvent> pieces = SplitLargeEvent(batch, limit);
    EXPECT_GT(pieces.size(), 1u);
    for (const v1::JobEvent& piece : pieces) EXPECT_LE(piece.ByteSizeLong(), limit);
    EXPECT_EQ(Join(pieces), Join({batch})) << "limit " << limit;
  }
}

TEST(SplitLargeEventTest, SnapshotsSplitByElementRange) {
  v1::JobEvent event;
  v1::LevelSnapshot* snapshot = event.mutable_snapshot();
  snapshot->set_level(0);
  snapshot->set_cluster_count(500000);
  snapshot->set_total_elements(500000);
  for (uint32_t i = 0; i < 500000; ++i) snapshot->add_labels(i * 5);
  const std::vector<v1::JobEvent> pieces = SplitLargeEvent(event, 100000);
  ASSERT_GT(pieces.size(), 10u);
  std::vector<uint32_t> joined;
  for (const v1::JobEvent& piece : pieces) {
    EXPECT_LE(piece.ByteSizeLong(), 100000u);
    EXPECT_EQ(piece.snapshot().first_element(), joined.size());
    EXPECT_EQ(piece.snapshot().total_elements(), 500000u);
    joined.insert(joined.end(), piece.snapshot().labels().begin(), piece.snapshot().labels().end());
  }
  EXPECT_EQ(joined, std::vector<uint32_t>(snapshot->labels().begin(), snapshot->labels().end()));
}

// A writer whose writes complete only when the test says (a client that stops reading).
class FakeWriter : public EventWriter {
 public:
  void StartWrite(const v1::JobEvent* event) override { written.push_back(*event); }
  void Finish(const grpc::Status& status) override {
    finished = true;
    this->status = status;
  }
  std::vector<v1::JobEvent> written;
  bool finished = false;
  grpc::Status status;
};

v1::JobEvent Progress(int n) {
  v1::JobEvent event;
  event.mutable_progress()->set_message(std::string(n, 'p'));
  return event;
}

TEST(ResultStoreTest, ProducingNeverWaitsAndAStalledReaderIsCutOffAtTheJobBudget) {
  MemoryBudget server_budget(uint64_t{1} << 30);
  FakeWriter writer;
  int cut_offs = 0;
  ResultStoreOptions options;
  options.job_budget_bytes = 100000;
  options.on_cut_off = [&](const grpc::Status&) { ++cut_offs; };
  ResultStore store(&writer, &server_budget, options);
  // The first write starts and never completes; the rest are held.
  int emitted = 0;
  while (store.Emit(Progress(1000))) ++emitted;
  EXPECT_GT(emitted, 50);
  EXPECT_LT(emitted, 110);
  EXPECT_TRUE(store.cancelled());
  EXPECT_TRUE(store.cancel_flag()->load());
  EXPECT_EQ(cut_offs, 1);
  EXPECT_EQ(store.held_bytes(), 0u);  // dropped at once, not when the client reads
  EXPECT_EQ(server_budget.used(), 0u);
  EXPECT_EQ(writer.written.size(), 1u);
  EXPECT_FALSE(writer.finished);  // one write in flight: the call ends when it completes
  store.Finish(v1::JobEvent(), grpc::Status::OK);  // the worker's late Finish is ignored
  store.OnWriteDone(true);
  ASSERT_EQ(writer.written.size(), 2u);
  EXPECT_TRUE(writer.written[1].final());
  EXPECT_EQ(writer.written[1].failed().code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  store.OnWriteDone(true);
  ASSERT_TRUE(writer.finished);
  EXPECT_EQ(writer.status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_NE(writer.status.error_message().find("read too slowly"), std::string::npos);
}

TEST(ResultStoreTest, TheServerWideBudgetIsSharedAndReturned) {
  MemoryBudget server_budget(150000);
  FakeWriter first_writer, second_writer;
  ResultStore first(&first_writer, &server_budget, {});
  ResultStore second(&second_writer, &server_budget, {});
  for (int i = 0; i < 60; ++i) ASSERT_TRUE(first.Emit(Progress(1000)));
  const uint64_t held_by_first = server_budget.used();
  EXPECT_GT(held_by_first, 50000u);
  int emitted = 0;
  while (second.Emit(Progress(1000))) ++emitted;
  EXPECT_LT(emitted, 100);
  EXPECT_TRUE(second.cancelled());
  EXPECT_FALSE(first.cancelled());
  EXPECT_EQ(server_budget.used(), held_by_first);
  // A reader that keeps up returns its share as it reads.
  while (!first_writer.finished && first.held_bytes() > 0) first.OnWriteDone(true);
  EXPECT_EQ(server_budget.used(), 0u);
}

TEST(ResultStoreTest, AReaderThatKeepsUpReceivesEverythingInOrder) {
  MemoryBudget server_budget(1 << 20);
  FakeWriter writer;
  ResultStoreOptions options;
  options.max_event_bytes = 4096;
  ResultStore store(&writer, &server_budget, options);
  const v1::JobEvent batch = MakeBatch(1, 3, 2000);
  ASSERT_TRUE(store.Emit(batch));
  v1::JobEvent done;
  done.mutable_done()->set_levels(4);
  store.Finish(done, grpc::Status::OK);
  while (!writer.finished) store.OnWriteDone(true);
  ASSERT_GT(writer.written.size(), 3u);
  EXPECT_TRUE(writer.written.back().final());
  EXPECT_TRUE(writer.written.back().has_done());
  writer.written.pop_back();
  for (const v1::JobEvent& e : writer.written) EXPECT_LE(e.ByteSizeLong(), 4096u);
  EXPECT_EQ(Join(writer.written), Join({batch}));
  EXPECT_TRUE(writer.status.ok());
  EXPECT_EQ(server_budget.used(), 0u);
}

TEST(ResultStoreTest, ClientCancelAndAbortSetTheJobsCancelFlag) {
  MemoryBudget server_budget(1 << 20);
  FakeWriter writer;
  ResultStore store(&writer, &server_budget, {});
  ASSERT_TRUE(store.Emit(Progress(10)));
  EXPECT_FALSE(store.cancel_flag()->load());
  store.OnCancel();
  EXPECT_TRUE(store.cancel_flag()->load());
  EXPECT_FALSE(store.Emit(Progress(10)));
  store.OnWriteDone(false);
  EXPECT_TRUE(writer.finished);
  EXPECT_EQ(writer.status.error_code(), grpc::StatusCode::CANCELLED);

  FakeWriter drained_writer;
  ResultStore drained(&drained_writer, &server_budget, {});
  drained.Abort(grpc::Status(grpc::StatusCode::UNAVAILABLE, "the server is shutting down"));
  EXPECT_TRUE(drained.cancel_flag()->load());
  ASSERT_EQ(drained_writer.written.size(), 1u);
  EXPECT_EQ(drained_writer.written[0].failed().code(), grpc::StatusCode::UNAVAILABLE);
  drained.OnWriteDone(true);
  EXPECT_EQ(drained_writer.status.error_code(), grpc::StatusCode::UNAVAILABLE);
}

}  // namespace
}  // namespace mlclust::server
