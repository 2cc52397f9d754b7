// The job registry and a job's record without the network: retention and memory drops
// leave a note under the right id; tenants; a record's levels read back by a cursor; an
// attached job's copy (RecordingChannel), packed triplets, and what it may not drop.
#include "server/job_record.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstring>

#include "absl/strings/str_replace.h"
#include "tests/server/hierarchy_events.h"

namespace mlclust::server {
namespace {

using ::testing::HasSubstr;

std::shared_ptr<JobRecord> Record(JobRegistry& registry, const std::string& id,
                                  const std::string& tenant = "", bool keep = true) {
  v1::JobSpec spec;
  spec.set_input_kind(v1::INPUT_KIND_DRACO_MESH);
  auto record = std::make_shared<JobRecord>(&registry, id, tenant, spec, keep, 1 << 20);
  registry.Add(record);
  return record;
}

// Level 0: labels 0..n-1; level l (1..n-1): element l moves to cluster 0.
void EmitHierarchy(EventChannel& record, uint32_t n) {
  ASSERT_TRUE(record.Emit(test_data::HierarchySnapshot(n)));
  ASSERT_TRUE(record.Emit(test_data::HierarchyLevels(n)));
}

TEST(JobRegistryTest, RetentionDropsEveryEndedJobUnderItsOwnId) {
  JobRegistryOptions options;
  options.retention = absl::ZeroDuration();
  JobRegistry registry(options);
  std::vector<std::shared_ptr<JobRecord>> records;
  for (const char* id : {"job-a", "job-b", "job-c"}) records.push_back(Record(registry, id));
  records[1]->MarkRunning();  // job-b still runs: kept
  records[0]->MarkEnded(grpc::Status::OK);
  records[2]->MarkEnded(grpc::Status(grpc::StatusCode::CANCELLED, "x"));
  registry.Sweep();
  EXPECT_EQ(registry.size(), 1u);
  EXPECT_EQ(registry.dropped(), 2u);
  for (const char* id : {"job-a", "job-c"}) {
    absl::StatusOr<std::shared_ptr<JobRecord>> found = registry.Find(id, "");
    EXPECT_EQ(found.status().code(), absl::StatusCode::kNotFound) << id;
    EXPECT_THAT(found.status().message(), HasSubstr(absl::StrCat("job ", id, ": ")));
    EXPECT_THAT(found.status().message(), HasSubstr("retention time"));
  }
  ASSERT_TRUE(registry.Find("job-b", "").ok());
  EXPECT_THAT(registry.Find("job-z", "").status().message(), HasSubstr("no job 'job-z'"));
}

TEST(JobRegistryTest, AnotherTenantsJobAnswersExactlyLikeAnUnknownId) {
  JobRegistryOptions options;
  options.retention = absl::ZeroDuration();
  JobRegistry registry(options);
  auto kept = Record(registry, "job-kept", "alpha");
  auto dropped = Record(registry, "job-gone", "alpha");
  dropped->MarkEnded(grpc::Status::OK);
  registry.Sweep();  // job-gone's results dropped, a note left for alpha
  // The unknown id's answer, with the id in place of "job-none".
  auto unknown_answer = [&](const std::string& id) {
    const absl::Status unknown = registry.Find("job-none", "beta").status();
    return absl::Status(unknown.code(), absl::StrReplaceAll(unknown.message(), {{"job-none", id}}));
  };
  for (const char* id : {"job-kept", "job-gone"}) {
    const absl::Status other = registry.Find(id, "beta").status();
    EXPECT_EQ(other.code(), absl::StatusCode::kNotFound) << id;
    EXPECT_EQ(other, unknown_answer(id)) << id;
  }
  ASSERT_TRUE(registry.Find("job-kept", "alpha").ok());
  EXPECT_THAT(registry.Find("job-gone", "alpha").status().message(), HasSubstr("retention time"));
}

TEST(JobRegistryTest, ListingByOwnerShowsOnlyThatConnectionsJobs) {
  JobRegistry registry(JobRegistryOptions{});
  for (const auto& [id, owner] :
       {std::pair{"job-1", "ipv4:127.0.0.1:1000"}, std::pair{"job-2", "ipv4:127.0.0.1:2000"},
        std::pair{"job-3", "ipv4:127.0.0.1:1000"}}) {
    v1::JobSpec spec;
    auto record = std::make_shared<JobRecord>(&registry, id, "", spec, true, 1 << 20);
    record->set_owner(owner);
    registry.Add(record);
  }
  const std::string first = "ipv4:127.0.0.1:1000", nobody = "ipv4:127.0.0.1:3000";
  std::vector<std::string> ids;
  for (const v1::JobSummary& job : registry.List("", &first)) ids.push_back(job.job_id());
  EXPECT_THAT(ids, ::testing::ElementsAre("job-1", "job-3"));
  EXPECT_TRUE(registry.List("", &nobody).empty());
  EXPECT_EQ(registry.List("").size(), 3u);
}

TEST(JobRegistryTest, MemoryForANewJobDropsTheOldestEndedFirst) {
  JobRegistryOptions options;
  options.kept_bytes_limit = 3000;
  JobRegistry registry(options);
  auto first = Record(registry, "job-1");
  EmitHierarchy(*first, 50);  // 200 + 49 * (12 + 24) = 1,964 bytes
  EXPECT_EQ(first->kept_bytes(), 1964u);
  EXPECT_EQ(registry.kept_bytes(), 1964u);
  first->MarkEnded(grpc::Status::OK);
  auto second = Record(registry, "job-2");
  EmitHierarchy(*second, 50);  // does not fit beside the first: the first goes
  EXPECT_EQ(registry.kept_bytes(), 1964u);
  EXPECT_THAT(registry.Find("job-1", "").status().message(), HasSubstr("make room"));
  // A running job is never dropped for another: the third cannot fit and is cancelled.
  auto third = Record(registry, "job-3");
  v1::JobEvent snapshot;
  snapshot.mutable_snapshot()->set_total_elements(500);
  for (int i = 0; i < 500; ++i) snapshot.mutable_snapshot()->add_labels(i);
  EXPECT_FALSE(third->Emit(snapshot));
  EXPECT_TRUE(third->cancelled());
  EXPECT_EQ(third->state(), JobState::kFailed);
  EXPECT_TRUE(registry.Find("job-2", "").ok());
}

TEST(JobRecordTest, ACursorReadsASnapshotAtAnyLevelThenTheRest) {
  JobRegistry registry({});
  auto record = Record(registry, "job-x");
  EmitHierarchy(*record, 10);
  v1::Done done;
  done.set_levels(10);
  record->Finish(
      [&] {
        v1::JobEvent event;
        *event.mutable_done() = done;
        return event;
      }(),
      grpc::Status::OK);
  WatchCursor cursor;
  cursor.from_level = 4;
  v1::JobEvent event;
  grpc::Status status;
  std::vector<v1::JobEvent> events;
  while (record->NextEvent(cursor, event, status, nullptr) == JobRecord::Next::kEvent) {
    events.push_back(event);
  }
  EXPECT_TRUE(status.ok());
  ASSERT_EQ(events.size(), 4u);  // accepted, snapshot, one batch, done
  EXPECT_EQ(events[0].accepted().job_id(), "job-x");
  const v1::LevelSnapshot& snapshot = events[1].snapshot();
  EXPECT_EQ(snapshot.level(), 4u);
  EXPECT_EQ(snapshot.cluster_count(), 6u);
  // Elements 1..4 have moved to cluster 0.
  EXPECT_THAT(snapshot.labels(), ::testing::ElementsAre(0, 0, 0, 0, 0, 5, 6, 7, 8, 9));
  const v1::LevelBatch& batch = events[2].levels();
  EXPECT_EQ(batch.first_level(), 5u);
  EXPECT_THAT(batch.element(), ::testing::ElementsAre(5, 6, 7, 8, 9));
  EXPECT_THAT(batch.triplet_end(), ::testing::ElementsAre(1, 2, 3, 4, 5));
  EXPECT_TRUE(events[3].has_done());
  EXPECT_TRUE(events[3].final());
}

// Found by fuzz/fuzz_watch_cancel.cc: resuming from level 4294967295 made the next level
// wrap to 0, and the watcher read before the first level (out of bounds, the server
// crashed). No level comes after the largest number: an ended job answers OUT_OF_RANGE.
TEST(JobRecordTest, ResumingFromTheLargestLevelNumberReadsNoLevel) {
  JobRegistry registry({});
  auto record = Record(registry, "job-x");
  EmitHierarchy(*record, 10);
  v1::JobEvent done;
  done.mutable_done()->set_levels(10);
  record->Finish(done, grpc::Status::OK);
  EXPECT_EQ(WatchCursorFor(3, true).next_level, 4u);
  EXPECT_EQ(WatchCursorFor(3, false).phase, WatchCursor::Phase::kHeader);
  WatchCursor cursor = WatchCursorFor(UINT32_MAX, true);
  EXPECT_EQ(cursor.next_level, UINT32_MAX);
  v1::JobEvent event;
  grpc::Status status;
  ASSERT_EQ(record->NextEvent(cursor, event, status, nullptr), JobRecord::Next::kEnd);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::OUT_OF_RANGE);
  EXPECT_THAT(status.error_message(), HasSubstr("level 4294967295 is past its last"));
}

// Issue 24, item 2: a thousand watchers of one job each held their own copy of the labels
// they started from. Watchers of one level share one copy, level 0 needs none, and the
// copy goes when the last of them has sent it.
TEST(JobRecordTest, WatchersOfOneLevelShareOneCopyOfItsLabels) {
  JobRegistry registry(JobRegistryOptions{});
  auto record = Record(registry, "job-s", "", /*keep=*/true);
  EmitHierarchy(*record, 10);
  record->MarkEnded(grpc::Status::OK);
  std::vector<WatchCursor> cursors(3);
  cursors[0].from_level = cursors[1].from_level = 4;  // cursors[2] from level 0
  v1::JobEvent event;
  grpc::Status status;
  for (WatchCursor& cursor : cursors) {
    ASSERT_EQ(record->NextEvent(cursor, event, status, nullptr), JobRecord::Next::kEvent);
    ASSERT_TRUE(event.has_accepted());
    ASSERT_EQ(record->NextEvent(cursor, event, status, nullptr), JobRecord::Next::kEvent);
    ASSERT_TRUE(event.has_snapshot());
  }
  // The whole snapshot fits one event, so each cursor has sent it: nothing is held.
  for (const WatchCursor& cursor : cursors) EXPECT_EQ(cursor.labels, nullptr);
  EXPECT_THAT(event.snapshot().labels(), ::testing::ElementsAre(0, 1, 2, 3, 4, 5, 6, 7, 8, 9));
}

TEST(JobRecordTest, WatchersOfOneLevelHoldTheSameLabelsWhileSendingThem) {
  JobRegistry registry(JobRegistryOptions{});
  v1::JobSpec spec;
  // Events of at most 4 KiB: a 5000-element snapshot goes in several pieces.
  auto record = std::make_shared<JobRecord>(&registry, "job-big", "", spec, true, 4096);
  registry.Add(record);
  EmitHierarchy(*record, 5000);
  record->MarkEnded(grpc::Status::OK);
  WatchCursor first, second, from_zero;
  first.from_level = second.from_level = 7;
  v1::JobEvent event;
  grpc::Status status;
  for (WatchCursor* cursor : {&first, &second, &from_zero}) {
    for (int i = 0; i < 2; ++i) {
      ASSERT_EQ(record->NextEvent(*cursor, event, status, nullptr), JobRecord::Next::kEvent);
    }
    ASSERT_TRUE(event.has_snapshot());
    ASSERT_LT(event.snapshot().labels_size(), 5000);  // more pieces to come
  }
  ASSERT_NE(first.labels, nullptr);
  EXPECT_EQ(first.labels.get(), second.labels.get());  // one copy for both
  EXPECT_EQ(from_zero.labels, nullptr);                // level 0: the record's own
  // The rest of the snapshot: level 7 has elements 1..7 in cluster 0.
  while (second.phase == WatchCursor::Phase::kSnapshot) {
    ASSERT_EQ(record->NextEvent(second, event, status, nullptr), JobRecord::Next::kEvent);
  }
  EXPECT_EQ(second.labels, nullptr);
  EXPECT_EQ(first.labels.use_count(), 1);  // only the first holds it now
}

// The call's side of an attached job: counts what reaches it.
class FakeCall : public EventChannel {
 public:
  bool Emit(v1::JobEvent event) override {
    events.push_back(std::move(event));
    return !cancelled_flag;
  }
  void Finish(v1::JobEvent final_event, const grpc::Status& status) override {
    events.push_back(std::move(final_event));
    finished_with = status;
  }
  bool cancelled() const override { return cancelled_flag.load(); }
  const std::atomic<bool>* cancel_flag() const override { return &cancelled_flag; }

  std::vector<v1::JobEvent> events;
  grpc::Status finished_with = grpc::Status(grpc::StatusCode::UNKNOWN, "not finished");
  std::atomic<bool> cancelled_flag{false};
};

std::string Packed(const std::vector<uint32_t>& values) {
  std::string bytes(values.size() * 4, '\0');
  std::memcpy(bytes.data(), values.data(), bytes.size());
  return bytes;
}

// Every event the cursor gives until the end, and the call's status.
std::vector<v1::JobEvent> ReadAll(JobRecord& record, WatchCursor cursor, grpc::Status& status) {
  std::vector<v1::JobEvent> events;
  v1::JobEvent event;
  while (record.NextEvent(cursor, event, status, nullptr) == JobRecord::Next::kEvent) {
    events.push_back(event);
  }
  return events;
}

TEST(RecordingChannelTest, AnAttachedJobsPackedLevelsReadBackFromItsRecord) {
  JobRegistry registry({});
  auto record = Record(registry, "job-p", "", /*keep=*/false);
  auto call = std::make_shared<FakeCall>();
  RecordingChannel channel(call, record);
  v1::JobEvent snapshot;
  snapshot.mutable_snapshot()->set_total_elements(4);
  snapshot.mutable_snapshot()->set_cluster_count(4);
  for (uint32_t i = 0; i < 4; ++i) snapshot.mutable_snapshot()->add_labels(i);
  EXPECT_TRUE(channel.Emit(snapshot));
  // Two levels in one packed batch: 3 -> 2, then 1 and 2 -> 0.
  v1::JobEvent levels;
  v1::LevelBatch* batch = levels.mutable_levels();
  batch->set_first_level(1);
  batch->add_cluster_count(3);
  batch->add_energy(1.5);
  batch->add_triplet_end(1);
  batch->add_cluster_count(2);
  batch->add_energy(2.5);
  batch->add_triplet_end(3);
  batch->set_packed_element(Packed({3, 1, 2}));
  batch->set_packed_to_cluster(Packed({2, 0, 0}));
  batch->set_packed_from_cluster(Packed({3, 1, 2}));
  EXPECT_TRUE(channel.Emit(levels));
  EXPECT_EQ(record->kept_bytes(), 4 * 4 + 3 * 12 + 2 * 24u);
  v1::JobEvent done;
  done.mutable_done()->set_levels(3);
  done.mutable_done()->set_triplets(3);
  channel.Finish(done, grpc::Status::OK);
  // The call got every event, untouched; the record ended with the same Done.
  ASSERT_EQ(call->events.size(), 3u);
  EXPECT_EQ(call->events[1].levels().packed_element(), Packed({3, 1, 2}));
  EXPECT_TRUE(call->finished_with.ok());
  EXPECT_EQ(record->state(), JobState::kSucceeded);
  const v1::JobSummary summary = record->Summary(absl::Now(), absl::Hours(1));
  EXPECT_FALSE(summary.detached());
  EXPECT_EQ(summary.levels(), 3u);
  EXPECT_EQ(summary.triplets(), 3u);

  WatchCursor cursor;
  cursor.from_level = 1;
  grpc::Status status;
  const std::vector<v1::JobEvent> events = ReadAll(*record, cursor, status);
  EXPECT_TRUE(status.ok()) << status.error_message();
  ASSERT_EQ(events.size(), 4u);  // accepted, snapshot at level 1, level 2, done
  EXPECT_FALSE(events[0].accepted().detached());
  EXPECT_THAT(events[1].snapshot().labels(), ::testing::ElementsAre(0, 1, 2, 2));
  EXPECT_EQ(events[1].snapshot().cluster_count(), 3u);
  EXPECT_EQ(events[2].levels().first_level(), 2u);
  EXPECT_THAT(events[2].levels().element(), ::testing::ElementsAre(1, 2));
  EXPECT_THAT(events[2].levels().to_cluster(), ::testing::ElementsAre(0, 0));
  EXPECT_THAT(events[2].levels().from_cluster(), ::testing::ElementsAre(1, 2));
  EXPECT_EQ(events[2].levels().energy(0), 2.5);
  EXPECT_EQ(events[3].done().levels(), 3u);
}

TEST(RecordingChannelTest, CancellationIsTheCallsAndAbortReachesBoth) {
  JobRegistry registry({});
  auto record = Record(registry, "job-c", "", /*keep=*/false);
  auto call = std::make_shared<FakeCall>();
  RecordingChannel channel(call, record);
  EXPECT_EQ(channel.cancel_flag(), &call->cancelled_flag);
  EXPECT_FALSE(channel.cancelled());
  call->cancelled_flag = true;  // the caller went away
  EXPECT_TRUE(channel.cancelled());
  v1::JobEvent progress;
  progress.mutable_progress()->set_stage("cluster");
  EXPECT_FALSE(channel.Emit(progress));
  channel.Abort(grpc::Status(grpc::StatusCode::CANCELLED, "by a Cancel call"));
  EXPECT_EQ(record->state(), JobState::kCancelled);
  EXPECT_EQ(call->finished_with.error_code(), grpc::StatusCode::CANCELLED);
}

TEST(RecordingChannelTest, AnAttachedJobThatDoesNotFitRunsOnWithoutDroppingDetachedResults) {
  JobRegistryOptions options;
  options.kept_bytes_limit = 3000;
  JobRegistry registry(options);
  auto detached = Record(registry, "job-d");
  EmitHierarchy(*detached, 50);  // 1,964 bytes
  detached->MarkEnded(grpc::Status::OK);
  auto record = Record(registry, "job-a", "", /*keep=*/false);
  auto call = std::make_shared<FakeCall>();
  RecordingChannel channel(call, record);
  v1::JobEvent snapshot;
  snapshot.mutable_snapshot()->set_total_elements(500);
  for (int i = 0; i < 500; ++i) snapshot.mutable_snapshot()->add_labels(i);
  EXPECT_TRUE(channel.Emit(snapshot));  // the job runs on for its caller
  EXPECT_FALSE(record->cancelled());
  EXPECT_EQ(call->events.size(), 1u);
  EXPECT_EQ(record->kept_bytes(), 0u);
  EXPECT_EQ(registry.kept_bytes(), 1964u);
  ASSERT_TRUE(registry.Find("job-d", "").ok());  // the detached job's results stay
  v1::JobEvent done;
  done.mutable_done()->set_levels(500);
  done.mutable_done()->set_triplets(499);
  channel.Finish(done, grpc::Status::OK);
  EXPECT_EQ(record->state(), JobState::kSucceeded);
  EXPECT_EQ(record->Summary(absl::Now(), absl::Hours(1)).levels(), 500u);
  grpc::Status status;
  EXPECT_TRUE(ReadAll(*record, WatchCursor(), status).empty());
  EXPECT_EQ(status.error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_THAT(status.error_message(), HasSubstr("were not kept"));
  EXPECT_THAT(status.error_message(), HasSubstr("the call that submitted it received them"));

  // An ended attached job's results do make room for a newer attached job.
  auto small = Record(registry, "job-s", "", /*keep=*/false);
  RecordingChannel small_channel(std::make_shared<FakeCall>(), small);
  EmitHierarchy(small_channel, 20);  // 80 + 19 * 36 = 764 bytes: fits beside job-d
  small->MarkEnded(grpc::Status::OK);
  auto newer = Record(registry, "job-n", "", /*keep=*/false);
  RecordingChannel newer_channel(std::make_shared<FakeCall>(), newer);
  v1::JobEvent more;
  more.mutable_snapshot()->set_total_elements(200);
  for (int i = 0; i < 200; ++i) more.mutable_snapshot()->add_labels(i);
  EXPECT_TRUE(newer_channel.Emit(more));
  EXPECT_EQ(newer->kept_bytes(), 800u);
  EXPECT_THAT(registry.Find("job-s", "").status().message(), HasSubstr("make room"));
  EXPECT_TRUE(registry.Find("job-d", "").ok());
}

}  // namespace
}  // namespace mlclust::server
