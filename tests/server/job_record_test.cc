// The job registry and a detached job's record without the network: retention and memory
// drops leave a note under the right id; tenants; a record's levels read back by a cursor.
#include "server/job_record.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

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
void EmitHierarchy(JobRecord& record, uint32_t n) {
  v1::JobEvent snapshot;
  snapshot.mutable_snapshot()->set_total_elements(n);
  snapshot.mutable_snapshot()->set_cluster_count(n);
  for (uint32_t i = 0; i < n; ++i) snapshot.mutable_snapshot()->add_labels(i);
  ASSERT_TRUE(record.Emit(snapshot));
  v1::JobEvent levels;
  v1::LevelBatch* batch = levels.mutable_levels();
  batch->set_first_level(1);
  for (uint32_t l = 1; l < n; ++l) {
    batch->add_cluster_count(n - l);
    batch->add_energy(l);
    batch->add_element(l);
    batch->add_to_cluster(0);
    batch->add_from_cluster(l);
    batch->add_triplet_end(l);
  }
  ASSERT_TRUE(record.Emit(levels));
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
  EXPECT_EQ(registry.Find("job-b", "other").status().code(), absl::StatusCode::kPermissionDenied);
  EXPECT_THAT(registry.Find("job-z", "").status().message(), HasSubstr("no job 'job-z'"));
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

}  // namespace
}  // namespace mlclust::server
