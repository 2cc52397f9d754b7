// Detached and attached jobs over loopback gRPC: submit with detach, Watch from any level
// while the job runs or after (attached jobs too), resume a broken stream, Cancel, ListJobs,
// and the retention time and memory budget that drop kept results (NOT_FOUND saying why).
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <condition_variable>
#include <mutex>
#include <thread>

#include "client/client.h"
#include "core/io/draco_codec.h"
#include "grpcpp/grpcpp.h"
#include "mlclust/v1/mlclust.grpc.pb.h"
#include "server/server.h"
#include "tests/fixtures/cutting_proxy.h"
#include "tests/fixtures/test_meshes.h"
#include "tests/fixtures/test_server.h"

namespace mlclust {
namespace {

using ::testing::HasSubstr;

using testing::ChannelTo;
using testing::ExpectSameHierarchy;
using testing::GetStats;

std::unique_ptr<server::Server> StartServer(server::ServerOptions options) {
  options.gpu = server::GpuMode::kOff;
  return testing::StartServer(std::move(options));
}

v1::JobSpec MeshSpec(v1::Algorithm algorithm, uint32_t clusters = 0) {
  return testing::MeshSpec(algorithm, clusters, "jobs_test");
}

v1::JobList List(const std::shared_ptr<grpc::Channel>& channel) {
  absl::StatusOr<v1::JobList> list = client::ListJobs(channel);
  EXPECT_TRUE(list.ok()) << list.status();
  return list.ok() ? *list : v1::JobList();
}

const v1::JobSummary* FindJob(const v1::JobList& list, const std::string& id) {
  for (const v1::JobSummary& job : list.jobs()) {
    if (job.job_id() == id) return &job;
  }
  return nullptr;
}

// Waits until job `id` has ended (ListJobs), up to 60 s.
void WaitEnded(const std::shared_ptr<grpc::Channel>& channel, const std::string& id) {
  for (int i = 0; i < 6000; ++i) {
    const v1::JobList list = List(channel);
    const v1::JobSummary* job = FindJob(list, id);
    if (job != nullptr && job->state() != "queued" && job->state() != "running") return;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ADD_FAILURE() << id << " did not end";
}

TEST(DetachTest, WatchersFromAnyLevelSeeTheLevelsOfAnAttachedRun) {
  std::unique_ptr<server::Server> server = StartServer({});
  ASSERT_TRUE(server);
  auto channel = ChannelTo(*server);
  const std::string bytes = *EncodeMeshToDraco(testing::Grid(40));  // 3,200 faces
  absl::StatusOr<client::JobResult> attached =
      client::RunJob(channel, MeshSpec(v1::ALGORITHM_ML), bytes);
  ASSERT_TRUE(attached.ok()) << attached.status();

  absl::StatusOr<v1::Accepted> accepted =
      client::SubmitDetached(channel, MeshSpec(v1::ALGORITHM_ML), bytes);
  ASSERT_TRUE(accepted.ok()) << accepted.status();
  EXPECT_TRUE(accepted->detached());
  EXPECT_EQ(accepted->input_bytes(), bytes.size());
  EXPECT_GT(accepted->retention_seconds(), 0);
  EXPECT_NE(accepted->job_id(), attached->job_id);

  // Two watchers at once, from the start and from level 3,000, on other channels.
  client::WatchOptions from_middle;
  from_middle.from_level = 3000;
  absl::StatusOr<client::JobResult> middle;
  std::thread second(
      [&] { middle = client::WatchJob(ChannelTo(*server), accepted->job_id(), from_middle); });
  absl::StatusOr<client::JobResult> whole =
      client::WatchJob(ChannelTo(*server), accepted->job_id());
  second.join();
  ASSERT_TRUE(whole.ok()) << whole.status();
  ASSERT_TRUE(middle.ok()) << middle.status();
  ExpectSameHierarchy(attached->hierarchy, whole->hierarchy);
  EXPECT_EQ(whole->first_level, 0u);
  EXPECT_EQ(middle->first_level, 3000u);
  ExpectSameHierarchy(attached->hierarchy, middle->hierarchy, 3000);
  EXPECT_EQ(whole->done.levels(), attached->done.levels());
  EXPECT_EQ(whole->done.triplets(), attached->done.triplets());

  // After the job ended, again: the same, and the first event repeats what Accepted said
  // about the input.
  v1::Accepted header;
  client::WatchOptions capture;
  capture.on_event = [&](const v1::JobEvent& event) {
    if (event.has_accepted()) header = event.accepted();
  };
  absl::StatusOr<client::JobResult> again = client::WatchJob(channel, accepted->job_id(), capture);
  ASSERT_TRUE(again.ok()) << again.status();
  ExpectSameHierarchy(attached->hierarchy, again->hierarchy);
  EXPECT_EQ(header.job_id(), accepted->job_id());
  EXPECT_TRUE(header.detached());
  EXPECT_FALSE(accepted->draco_method().empty());
  EXPECT_EQ(header.draco_method(), accepted->draco_method());
  EXPECT_EQ(header.face_order(), accepted->face_order());

  // The list knows both jobs, in order, with their state.
  const v1::JobList list = List(channel);
  ASSERT_EQ(list.jobs_size(), 2);
  EXPECT_EQ(list.jobs(0).job_id(), attached->job_id);
  EXPECT_FALSE(list.jobs(0).detached());
  // The attached job's levels are kept too (the same levels, the same bytes).
  EXPECT_EQ(list.jobs(0).kept_bytes(), list.jobs(1).kept_bytes());
  EXPECT_EQ(list.jobs(1).job_id(), accepted->job_id());
  EXPECT_TRUE(list.jobs(1).detached());
  for (const v1::JobSummary& job : list.jobs()) {
    EXPECT_EQ(job.state(), "succeeded");
    EXPECT_EQ(job.levels(), attached->done.levels());
    EXPECT_EQ(job.triplets(), attached->done.triplets());
    EXPECT_EQ(job.label(), "jobs_test");
    EXPECT_GT(job.expires_in_seconds(), 0);
  }
  // 4 bytes per label, 12 per triplet, and a little per level.
  EXPECT_GE(list.jobs(1).kept_bytes(), 4 * 3200 + 12 * attached->done.triplets());
  auto stub = v1::Clustering::NewStub(channel);
  v1::Stats stats;
  // A Watch call counts as active until its handler returns, which can be a moment after
  // the client read the last event (on a loaded machine): wait for it, up to 10 s.
  for (int i = 0; i < 200; ++i) {
    grpc::ClientContext context;
    ASSERT_TRUE(stub->GetStats(&context, v1::GetStatsRequest(), &stats).ok());
    if (stats.watch_calls_active() == 0) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  EXPECT_EQ(stats.jobs_known(), 2u);
  EXPECT_EQ(stats.kept_result_bytes(), list.jobs(0).kept_bytes() + list.jobs(1).kept_bytes());
  EXPECT_EQ(stats.watch_calls_active(), 0u);
}

TEST(DetachTest, AWatchStartedWhileTheJobIsQueuedFollowsItToTheEnd) {
  std::unique_ptr<server::Server> server = StartServer({});  // one worker
  ASSERT_TRUE(server);
  auto channel = ChannelTo(*server);
  const std::string small = *EncodeMeshToDraco(testing::Grid(30));
  absl::StatusOr<client::JobResult> solo =
      client::RunJob(channel, MeshSpec(v1::ALGORITHM_HC), small);
  ASSERT_TRUE(solo.ok()) << solo.status();
  // A longer job first keeps the worker busy while the watched one waits.
  absl::StatusOr<v1::Accepted> blocker = client::SubmitDetached(
      channel, MeshSpec(v1::ALGORITHM_ML), *EncodeMeshToDraco(testing::Grid(200)));
  ASSERT_TRUE(blocker.ok()) << blocker.status();
  absl::StatusOr<v1::Accepted> watched =
      client::SubmitDetached(channel, MeshSpec(v1::ALGORITHM_HC), small);
  ASSERT_TRUE(watched.ok()) << watched.status();
  std::vector<std::string> stages;
  client::WatchOptions options;
  options.on_event = [&](const v1::JobEvent& event) {
    if (event.has_progress()) stages.push_back(event.progress().stage());
  };
  absl::StatusOr<client::JobResult> result = client::WatchJob(channel, watched->job_id(), options);
  ASSERT_TRUE(result.ok()) << result.status();
  ExpectSameHierarchy(solo->hierarchy, result->hierarchy);
  EXPECT_FALSE(stages.empty());  // it saw the job's progress while waiting for levels
}

TEST(DetachTest, ABrokenStreamResumesWhereItStopped) {
  server::ServerOptions options;
  options.max_event_bytes = 8 << 10;  // many small events, and split levels
  std::unique_ptr<server::Server> server = StartServer(options);
  ASSERT_TRUE(server);
  auto channel = ChannelTo(*server);
  const std::string bytes = *EncodeMeshToDraco(testing::Grid(40));
  absl::StatusOr<client::JobResult> solo =
      client::RunJob(channel, MeshSpec(v1::ALGORITHM_HC), bytes);
  ASSERT_TRUE(solo.ok()) << solo.status();
  absl::StatusOr<v1::Accepted> accepted =
      client::SubmitDetached(channel, MeshSpec(v1::ALGORITHM_HC), bytes);
  ASSERT_TRUE(accepted.ok()) << accepted.status();
  WaitEnded(channel, accepted->job_id());

  // Read the snapshot and a few level batches, then break the stream.
  auto stub = v1::Clustering::NewStub(channel);
  std::vector<uint32_t> counts;   // cluster count per complete level received
  std::vector<uint64_t> moves;    // triplets per complete level
  uint64_t open_level_moves = 0;  // of a split level not complete yet
  auto take = [&](const v1::JobEvent& event) {
    if (event.has_snapshot() && event.snapshot().first_element() == 0) {
      counts.push_back(event.snapshot().cluster_count());
      moves.push_back(0);
    }
    if (!event.has_levels()) return;
    const v1::LevelBatch& batch = event.levels();
    ASSERT_EQ(batch.first_level(), counts.size()) << "levels out of order";
    uint32_t begin = 0;
    for (int i = 0; i < batch.cluster_count_size(); ++i) {
      const uint64_t n = batch.triplet_end(i) - begin + open_level_moves;
      begin = batch.triplet_end(i);
      if (i == batch.cluster_count_size() - 1 && batch.last_level_continues()) {
        open_level_moves = n;
      } else {
        open_level_moves = 0;
        counts.push_back(batch.cluster_count(i));
        moves.push_back(n);
      }
    }
  };
  {
    grpc::ClientContext context;
    v1::WatchRequest request;
    request.set_job_id(accepted->job_id());
    auto stream = stub->Watch(&context, request);
    v1::JobEvent event;
    int batches = 0;
    while (batches < 5 && stream->Read(&event)) {
      take(event);
      batches += event.has_levels();
    }
    context.TryCancel();
    while (stream->Read(&event)) {
    }
    EXPECT_EQ(stream->Finish().error_code(), grpc::StatusCode::CANCELLED);
  }
  ASSERT_GT(counts.size(), 1u);
  ASSERT_LT(counts.size(), solo->hierarchy.num_levels());
  // Resume after the last complete level: no snapshot, no Accepted, the rest to Done.
  open_level_moves = 0;
  grpc::ClientContext context;
  v1::WatchRequest request;
  request.set_job_id(accepted->job_id());
  request.set_from_level(static_cast<uint32_t>(counts.size() - 1));
  request.set_resume(true);
  auto stream = stub->Watch(&context, request);
  v1::JobEvent event;
  bool done = false;
  while (stream->Read(&event)) {
    EXPECT_FALSE(event.has_snapshot() || event.has_accepted());
    take(event);
    done = done || event.has_done();
  }
  ASSERT_TRUE(stream->Finish().ok());
  EXPECT_TRUE(done);
  ASSERT_EQ(counts.size(), solo->hierarchy.num_levels());
  uint64_t total = 0;
  for (size_t level = 0; level < counts.size(); ++level) {
    EXPECT_EQ(counts[level], solo->hierarchy.cluster_count(level)) << "level " << level;
    total += moves[level];
  }
  EXPECT_EQ(total, solo->hierarchy.num_moves());
}

// Job ids are capabilities: 128 random bits, so an id tells nothing of the others; without
// tokens a caller lists only its own connection's jobs, and any connection holding an id
// may watch and cancel it.
TEST(JobIdsTest, IdsAreRandomAndOthersJobsAreNotListedWithoutTokens) {
  std::unique_ptr<server::Server> server = StartServer({});
  ASSERT_TRUE(server);
  auto owner = testing::OwnConnectionTo(*server);
  auto other = testing::OwnConnectionTo(*server);
  const std::string bytes = *EncodeMeshToDraco(testing::Grid(10));
  std::vector<std::string> ids;
  for (int i = 0; i < 3; ++i) {
    absl::StatusOr<v1::Accepted> accepted =
        client::SubmitDetached(owner, MeshSpec(v1::ALGORITHM_HC), bytes);
    ASSERT_TRUE(accepted.ok()) << accepted.status();
    ids.push_back(accepted->job_id());
  }
  for (const std::string& id : ids) {
    EXPECT_THAT(id, ::testing::MatchesRegex("job-[0-9a-f]{32}")) << id;
  }
  EXPECT_NE(ids[0], ids[1]);
  EXPECT_NE(ids[1], ids[2]);
  // Only the owner's connection lists them.
  EXPECT_EQ(List(owner).jobs_size(), 3);
  EXPECT_EQ(List(other).jobs_size(), 0);
  // The id is enough to watch from another connection.
  WaitEnded(owner, ids[2]);
  absl::StatusOr<client::JobResult> watched = client::WatchJob(other, ids[2]);
  ASSERT_TRUE(watched.ok()) << watched.status();
  EXPECT_EQ(watched->hierarchy.num_levels(), 200u);
}

TEST(JobIdsTest, ListAllJobsShowsEveryConnectionsJobs) {
  server::ServerOptions options;
  options.list_all_jobs = true;
  std::unique_ptr<server::Server> server = StartServer(options);
  ASSERT_TRUE(server);
  auto owner = testing::OwnConnectionTo(*server);
  auto other = testing::OwnConnectionTo(*server);
  absl::StatusOr<v1::Accepted> accepted = client::SubmitDetached(
      owner, MeshSpec(v1::ALGORITHM_HC), *EncodeMeshToDraco(testing::Grid(10)));
  ASSERT_TRUE(accepted.ok()) << accepted.status();
  const v1::JobList list = List(other);
  ASSERT_EQ(list.jobs_size(), 1);
  EXPECT_EQ(list.jobs(0).job_id(), accepted->job_id());
}

// Issue 24, item 2: Watch calls had no admission (1,000 unread watchers of one job took
// 2.3 GiB). They are admitted like Run calls, and a watcher whose client reads nothing is
// cut off: its slot comes back at once and it learns why (and to watch again) when it
// reads.
TEST(WatchLimitsTest, WatchersAreAdmittedLikeRunsAndUnreadOnesAreCutOff) {
  server::ServerOptions options;
  options.max_calls_per_connection = 3;
  options.watch_idle_timeout = absl::Milliseconds(300);
  std::unique_ptr<server::Server> server = StartServer(options);
  ASSERT_TRUE(server);
  auto channel = ChannelTo(*server);
  absl::StatusOr<v1::Accepted> accepted = client::SubmitDetached(
      channel, MeshSpec(v1::ALGORITHM_HC), *EncodeMeshToDraco(testing::Grid(120)));
  ASSERT_TRUE(accepted.ok()) << accepted.status();
  const std::string id = accepted->job_id();
  WaitEnded(channel, id);

  auto narrow = testing::NarrowChannelTo(*server);
  auto stub = v1::Clustering::NewStub(narrow);
  struct Watcher {
    grpc::ClientContext context;
    std::unique_ptr<grpc::ClientReader<v1::JobEvent>> stream;
  };
  std::vector<std::unique_ptr<Watcher>> watchers;
  v1::WatchRequest request;
  request.set_job_id(id);
  for (int i = 0; i < 4; ++i) {
    auto watcher = std::make_unique<Watcher>();
    watcher->context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(120));
    watcher->stream = stub->Watch(&watcher->context, request);
    watchers.push_back(std::move(watcher));
    // Admitted before the next one starts (calls started together arrive in any order).
    for (int wait = 0; i < 3 && wait < 1000 && GetStats(channel).calls_active() <= uint32_t(i);
         ++wait) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }
  // The fourth on that connection is refused like a fourth Run call.
  {
    v1::JobEvent event;
    EXPECT_FALSE(watchers[3]->stream->Read(&event));
    const grpc::Status refused = watchers[3]->stream->Finish();
    EXPECT_EQ(refused.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
    EXPECT_THAT(refused.error_message(), HasSubstr("per connection"));
  }
  // The three read nothing: cut off, their slots back.
  for (int i = 0; i < 3000 && GetStats(channel).readers_cut_off() < 3; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  const v1::Stats stats = GetStats(channel);
  EXPECT_EQ(stats.readers_cut_off(), 3u);
  EXPECT_EQ(stats.calls_active(), 0u);
  // Another client watches the whole job meanwhile.
  absl::StatusOr<client::JobResult> watched = client::WatchJob(channel, id);
  ASSERT_TRUE(watched.ok()) << watched.status();
  EXPECT_EQ(watched->hierarchy.num_levels(), 28800u);
  // A cut-off watcher that reads again learns why, and what to do.
  for (int i = 0; i < 3; ++i) {
    v1::JobEvent event;
    while (watchers[i]->stream->Read(&event)) {
    }
    const grpc::Status status = watchers[i]->stream->Finish();
    EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
    EXPECT_THAT(status.error_message(), HasSubstr("the client read nothing for"));
    EXPECT_THAT(status.error_message(), HasSubstr(absl::StrCat("watch ", id, " again")));
  }
}

TEST(DetachTest, UnknownDroppedAndUnkeptJobsAreRefusedWithReasons) {
  server::ServerOptions options;
  options.result_retention = absl::Seconds(1);
  std::unique_ptr<server::Server> server = StartServer(options);
  ASSERT_TRUE(server);
  auto channel = ChannelTo(*server);
  const std::string bytes = *EncodeMeshToDraco(testing::Grid(10));
  absl::StatusOr<client::JobResult> unknown = client::WatchJob(channel, "job-424242");
  EXPECT_EQ(unknown.status().code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(unknown.status().message(), HasSubstr("no job 'job-424242'"));

  absl::StatusOr<client::JobResult> attached =
      client::RunJob(channel, MeshSpec(v1::ALGORITHM_HC), bytes);
  ASSERT_TRUE(attached.ok());

  absl::StatusOr<v1::Accepted> accepted =
      client::SubmitDetached(channel, MeshSpec(v1::ALGORITHM_HC), bytes);
  ASSERT_TRUE(accepted.ok());
  WaitEnded(channel, accepted->job_id());
  client::WatchOptions past_end;
  past_end.from_level = 200;  // 200 faces: levels 0..199
  absl::StatusOr<client::JobResult> out_of_range =
      client::WatchJob(channel, accepted->job_id(), past_end);
  EXPECT_EQ(out_of_range.status().code(), absl::StatusCode::kOutOfRange);
  EXPECT_THAT(out_of_range.status().message(), HasSubstr("200 levels"));
  ASSERT_TRUE(client::WatchJob(channel, accepted->job_id()).ok());

  // Past the retention time: dropped, and the message says so.
  std::this_thread::sleep_for(std::chrono::milliseconds(2500));
  absl::StatusOr<client::JobResult> dropped = client::WatchJob(channel, accepted->job_id());
  EXPECT_EQ(dropped.status().code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(dropped.status().message(), HasSubstr("retention time"));
  EXPECT_EQ(List(channel).jobs_size(), 0);
  auto stub = v1::Clustering::NewStub(channel);
  grpc::ClientContext context;
  v1::Stats stats;
  ASSERT_TRUE(stub->GetStats(&context, v1::GetStatsRequest(), &stats).ok());
  EXPECT_EQ(stats.results_dropped(), 2u);
  EXPECT_EQ(stats.kept_result_bytes(), 0u);
  EXPECT_EQ(stats.jobs_known(), 0u);
}

TEST(DetachTest, TheMemoryBudgetDropsTheOldestResultsFirstAndCancelsWhatCannotFit) {
  const std::string bytes = *EncodeMeshToDraco(testing::Grid(30));  // 1,800 faces
  uint64_t one_job = 0;
  {
    std::unique_ptr<server::Server> server = StartServer({});
    auto channel = ChannelTo(*server);
    absl::StatusOr<v1::Accepted> accepted =
        client::SubmitDetached(channel, MeshSpec(v1::ALGORITHM_HC), bytes);
    ASSERT_TRUE(accepted.ok());
    WaitEnded(channel, accepted->job_id());
    one_job = FindJob(List(channel), accepted->job_id())->kept_bytes();
  }
  ASSERT_GT(one_job, 0u);
  server::ServerOptions options;
  options.kept_results_bytes = one_job + one_job / 2;  // room for one job's levels
  std::unique_ptr<server::Server> server = StartServer(options);
  auto channel = ChannelTo(*server);
  absl::StatusOr<v1::Accepted> first =
      client::SubmitDetached(channel, MeshSpec(v1::ALGORITHM_HC), bytes);
  ASSERT_TRUE(first.ok());
  WaitEnded(channel, first->job_id());
  absl::StatusOr<v1::Accepted> second =
      client::SubmitDetached(channel, MeshSpec(v1::ALGORITHM_HC), bytes);
  ASSERT_TRUE(second.ok());
  WaitEnded(channel, second->job_id());
  absl::StatusOr<client::JobResult> dropped = client::WatchJob(channel, first->job_id());
  EXPECT_EQ(dropped.status().code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(dropped.status().message(), HasSubstr("make room"));
  absl::StatusOr<client::JobResult> kept = client::WatchJob(channel, second->job_id());
  ASSERT_TRUE(kept.ok()) << kept.status();
  EXPECT_EQ(kept->done.triplets(), kept->hierarchy.num_moves());

  // A job bigger than the whole budget is cancelled, saying why.
  absl::StatusOr<v1::Accepted> too_big = client::SubmitDetached(
      channel, MeshSpec(v1::ALGORITHM_HC), *EncodeMeshToDraco(testing::Grid(60)));
  ASSERT_TRUE(too_big.ok());
  absl::StatusOr<client::JobResult> refused = client::WatchJob(channel, too_big->job_id());
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(refused.status().message(), HasSubstr("memory for kept results"));
  // The server keeps serving. An attached job whose levels do not fit beside the detached
  // ones' runs on for its caller, does not drop a detached job's results, and says why it
  // cannot be watched.
  absl::StatusOr<client::JobResult> attached =
      client::RunJob(channel, MeshSpec(v1::ALGORITHM_HC), *EncodeMeshToDraco(testing::Grid(60)));
  ASSERT_TRUE(attached.ok()) << attached.status();
  EXPECT_EQ(attached->hierarchy.num_levels(), 7200u);
  absl::StatusOr<client::JobResult> unkept = client::WatchJob(channel, attached->job_id);
  EXPECT_EQ(unkept.status().code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(unkept.status().message(), HasSubstr("were not kept"));
  // The cancelled detached job's record (and the part of its levels it kept) stays.
  EXPECT_EQ(client::WatchJob(channel, too_big->job_id()).status().code(),
            absl::StatusCode::kResourceExhausted);
  EXPECT_TRUE(client::RunJob(channel, MeshSpec(v1::ALGORITHM_HC), bytes).ok());
}

TEST(DetachTest, AnAttachedJobCanBeWatchedWhileItRunsAndAfter) {
  std::unique_ptr<server::Server> server = StartServer({});
  ASSERT_TRUE(server);
  auto channel = ChannelTo(*server);
  const std::string bytes = *EncodeMeshToDraco(testing::Grid(200));  // 80,000 faces
  // The attached run (packed triplets, the C++ client's default) tells its id in Accepted;
  // a watcher starts from level 70,000 as soon as it knows it, while the job runs.
  std::mutex mutex;
  std::condition_variable known;
  std::string id;
  client::RunOptions run_options;
  run_options.on_event = [&](const v1::JobEvent& event) {
    if (!event.has_accepted()) return;
    std::lock_guard<std::mutex> lock(mutex);
    id = event.accepted().job_id();
    known.notify_all();
  };
  absl::StatusOr<client::JobResult> attached;
  std::thread runner(
      [&] { attached = client::RunJob(channel, MeshSpec(v1::ALGORITHM_ML), bytes, run_options); });
  {
    std::unique_lock<std::mutex> lock(mutex);
    known.wait(lock, [&] { return !id.empty(); });
  }
  client::WatchOptions from_level;
  from_level.from_level = 70000;
  v1::Accepted header;
  from_level.on_event = [&](const v1::JobEvent& event) {
    if (event.has_accepted()) header = event.accepted();
  };
  absl::StatusOr<client::JobResult> during = client::WatchJob(ChannelTo(*server), id, from_level);
  runner.join();
  ASSERT_TRUE(attached.ok()) << attached.status();
  ASSERT_TRUE(during.ok()) << during.status();
  EXPECT_EQ(header.job_id(), id);
  EXPECT_FALSE(header.detached());
  EXPECT_EQ(during->first_level, 70000u);
  ExpectSameHierarchy(attached->hierarchy, during->hierarchy, 70000);
  EXPECT_EQ(during->done.levels(), attached->done.levels());
  // After it ended, from the start: every level again.
  absl::StatusOr<client::JobResult> after = client::WatchJob(channel, id);
  ASSERT_TRUE(after.ok()) << after.status();
  ExpectSameHierarchy(attached->hierarchy, after->hierarchy);
  const v1::JobList list = List(channel);
  const v1::JobSummary* summary = FindJob(list, id);
  ASSERT_NE(summary, nullptr);
  EXPECT_FALSE(summary->detached());
  EXPECT_EQ(summary->state(), "succeeded");
  EXPECT_GE(summary->kept_bytes(), 4 * 80000 + 12 * attached->done.triplets());
}

TEST(DetachTest, CancelEndsQueuedAndRunningJobs) {
  std::unique_ptr<server::Server> server = StartServer({});  // one worker
  ASSERT_TRUE(server);
  auto channel = ChannelTo(*server);
  const std::string big = *EncodeMeshToDraco(testing::Grid(300));  // 180,000 faces
  absl::StatusOr<v1::Accepted> running =
      client::SubmitDetached(channel, MeshSpec(v1::ALGORITHM_ML), big);
  absl::StatusOr<v1::Accepted> queued =
      client::SubmitDetached(channel, MeshSpec(v1::ALGORITHM_ML), big);
  ASSERT_TRUE(running.ok() && queued.ok());
  EXPECT_LE(queued->queue_position(), 1u);

  absl::StatusOr<std::string> state = client::CancelJob(channel, queued->job_id());
  ASSERT_TRUE(state.ok()) << state.status();
  EXPECT_EQ(*state, "cancelled");
  absl::StatusOr<client::JobResult> watched = client::WatchJob(channel, queued->job_id());
  EXPECT_EQ(watched.status().code(), absl::StatusCode::kCancelled);
  EXPECT_THAT(watched.status().message(), HasSubstr("Cancel call"));

  // The running one: its watcher ends with CANCELLED soon after the cancel.
  absl::StatusOr<client::JobResult> running_watch;
  std::thread watcher([&] { running_watch = client::WatchJob(channel, running->job_id()); });
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  ASSERT_TRUE(client::CancelJob(channel, running->job_id()).ok());
  watcher.join();
  EXPECT_EQ(running_watch.status().code(), absl::StatusCode::kCancelled);
  WaitEnded(channel, running->job_id());
  EXPECT_EQ(FindJob(List(channel), running->job_id())->state(), "cancelled");
  // Cancelling an ended job leaves it as it is; an unknown one is NOT_FOUND.
  EXPECT_EQ(*client::CancelJob(channel, running->job_id()), "cancelled");
  EXPECT_EQ(client::CancelJob(channel, "job-999999").status().code(), absl::StatusCode::kNotFound);
  // The worker is free again.
  EXPECT_TRUE(
      client::RunJob(channel, MeshSpec(v1::ALGORITHM_HC), *EncodeMeshToDraco(testing::Grid(5)))
          .ok());
}

// Many watchers at once, started while the job runs, some from late levels, some cancelled
// half-way: every one that reads to the end gets the levels of a solo run.
TEST(DetachTest, ManyWatchersOfARunningJobAllSeeTheSameLevels) {
  server::ServerOptions options;
  options.max_event_bytes = 32 << 10;
  std::unique_ptr<server::Server> server = StartServer(options);
  ASSERT_TRUE(server);
  auto channel = ChannelTo(*server);
  const std::string bytes = *EncodeMeshToDraco(testing::Grid(120));  // 28,800 faces
  absl::StatusOr<client::JobResult> solo =
      client::RunJob(channel, MeshSpec(v1::ALGORITHM_ML), bytes);
  ASSERT_TRUE(solo.ok()) << solo.status();
  absl::StatusOr<v1::Accepted> accepted =
      client::SubmitDetached(channel, MeshSpec(v1::ALGORITHM_ML), bytes);
  ASSERT_TRUE(accepted.ok());
  constexpr int kWatchers = 12;
  std::vector<absl::StatusOr<client::JobResult>> results(kWatchers);
  std::vector<std::thread> threads;
  for (int i = 0; i < kWatchers; ++i) {
    threads.emplace_back([&, i] {
      client::WatchOptions watch;
      watch.from_level = i % 3 == 0 ? 0 : 20000 + 500 * i;  // below 28,800
      // Every fourth gives up after a while (its call cancelled: the job runs on).
      if (i % 4 == 3) watch.deadline = absl::Milliseconds(50);
      results[i] = client::WatchJob(ChannelTo(*server), accepted->job_id(), watch);
    });
  }
  for (std::thread& thread : threads) thread.join();
  int complete = 0;
  for (int i = 0; i < kWatchers; ++i) {
    if (i % 4 == 3 && !results[i].ok()) {
      EXPECT_EQ(results[i].status().code(), absl::StatusCode::kDeadlineExceeded);
      continue;
    }
    ASSERT_TRUE(results[i].ok()) << i << ": " << results[i].status();
    ExpectSameHierarchy(solo->hierarchy, results[i]->hierarchy, results[i]->first_level);
    ++complete;
  }
  EXPECT_GE(complete, 9);
  WaitEnded(channel, accepted->job_id());
  EXPECT_EQ(FindJob(List(channel), accepted->job_id())->state(), "succeeded");
  auto stub = v1::Clustering::NewStub(channel);
  grpc::ClientContext context;
  v1::Stats stats;
  ASSERT_TRUE(stub->GetStats(&context, v1::GetStatsRequest(), &stats).ok());
  EXPECT_EQ(stats.watch_calls_active(), 0u);
}

// Drain: a queued detached job ends with UNAVAILABLE; its watcher gets that final status
// at once (not taken for a broken stream and retried), the running job's watcher its Done.
TEST(DetachTest, DrainEndsQueuedDetachedJobsAndTheirWatchers) {
  server::ServerOptions options;
  options.drain_time = absl::Seconds(60);
  std::unique_ptr<server::Server> server = StartServer(options);  // one worker
  ASSERT_TRUE(server);
  auto channel = ChannelTo(*server);
  absl::StatusOr<v1::Accepted> running = client::SubmitDetached(
      channel, MeshSpec(v1::ALGORITHM_HC), *EncodeMeshToDraco(testing::Grid(300)));
  absl::StatusOr<v1::Accepted> queued = client::SubmitDetached(
      channel, MeshSpec(v1::ALGORITHM_HC), *EncodeMeshToDraco(testing::Grid(10)));
  ASSERT_TRUE(running.ok() && queued.ok());
  int resumes = 0;
  client::WatchOptions watch;
  watch.on_resume = [&](const absl::Status&) { ++resumes; };
  absl::StatusOr<client::JobResult> running_result, queued_result;
  std::thread running_watcher(
      [&] { running_result = client::WatchJob(channel, running->job_id(), watch); });
  std::thread queued_watcher(
      [&] { queued_result = client::WatchJob(channel, queued->job_id(), watch); });
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  server->Shutdown();
  running_watcher.join();
  queued_watcher.join();
  EXPECT_EQ(resumes, 0);
  ASSERT_TRUE(running_result.ok()) << running_result.status();
  EXPECT_EQ(running_result->hierarchy.num_levels(), 180000u);
  EXPECT_EQ(queued_result.status().code(), absl::StatusCode::kUnavailable);
  EXPECT_THAT(queued_result.status().message(), HasSubstr("shutting down"));
}

}  // namespace
}  // namespace mlclust

namespace mlclust {
namespace {

using testing::CuttingProxy;

// The client's own resume: the connection breaks in the middle of the levels, WatchJob
// reconnects and asks for the levels after the last complete one; the result is whole.
TEST(DetachTest, WatchJobResumesAfterTheConnectionBreaks) {
  server::ServerOptions options;
  options.max_event_bytes = 16 << 10;
  std::unique_ptr<server::Server> server = StartServer(options);
  ASSERT_TRUE(server);
  auto channel = ChannelTo(*server);
  const std::string bytes = *EncodeMeshToDraco(testing::Grid(60));  // 7,200 faces
  absl::StatusOr<client::JobResult> solo =
      client::RunJob(channel, MeshSpec(v1::ALGORITHM_HC), bytes);
  ASSERT_TRUE(solo.ok()) << solo.status();
  absl::StatusOr<v1::Accepted> accepted =
      client::SubmitDetached(channel, MeshSpec(v1::ALGORITHM_HC), bytes);
  ASSERT_TRUE(accepted.ok());
  WaitEnded(channel, accepted->job_id());

  CuttingProxy proxy(server->port(), 100 << 10);  // the stream is ~400 KB
  int resumes = 0;
  client::WatchOptions watch;
  watch.resume_delay = absl::Milliseconds(50);
  watch.on_resume = [&](const absl::Status& status) {
    ++resumes;
    EXPECT_EQ(status.code(), absl::StatusCode::kUnavailable) << status;
  };
  absl::StatusOr<client::JobResult> result = client::WatchJob(
      client::Connect(absl::StrCat("127.0.0.1:", proxy.port())), accepted->job_id(), watch);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_EQ(resumes, 1);
  EXPECT_EQ(proxy.connections(), 2);
  ExpectSameHierarchy(solo->hierarchy, result->hierarchy);
  EXPECT_EQ(result->hierarchy.num_moves(), solo->hierarchy.num_moves());
}

}  // namespace
}  // namespace mlclust
