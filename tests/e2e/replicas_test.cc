// Several servers behind one client (client/replicas.h) on loopback: a replica that is
// gone or that drops connections before accepting a job is skipped, every job finishes
// with the levels of a solo run, a detached job's id names its replica; a replica lost
// after accepting a job (its connection cut in the middle of the levels, never to come
// back) loses no job: it is submitted again, the levels received kept and each passed on
// once, within a bounded number of tries; a job cancelled on its replica is not.
#include "client/replicas.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <thread>

#include "absl/strings/str_cat.h"
#include "client/client.h"
#include "core/io/draco_codec.h"
#include "grpc/health/v1/health.grpc.pb.h"
#include "server/server.h"
#include "tests/fixtures/cutting_proxy.h"
#include "tests/fixtures/loopback.h"
#include "tests/fixtures/test_meshes.h"
#include "tests/fixtures/test_server.h"

namespace mlclust {
namespace {

using ::testing::HasSubstr;

using testing::AddressOf;
using testing::CuttingProxy;
using testing::ExpectSameHierarchy;

// Replicas that list every connection's jobs (serve --list-all-jobs): the tests count what
// a replica ran from a connection of their own.
std::unique_ptr<server::Server> StartServer() {
  server::ServerOptions options;
  options.gpu = server::GpuMode::kOff;
  options.list_all_jobs = true;
  return testing::StartServer(options);
}

v1::JobSpec MeshSpec() { return testing::MeshSpec(v1::ALGORITHM_ML, 0, "replicas_test"); }

// A port that accepts TCP connections and closes them at once (a replica dying as each
// call arrives, before any job is accepted).
class ClosingListener {
 public:
  ClosingListener() {
    fd_ = testing::ListenOnLoopback(64, port_);
    thread_ = std::thread([this] {
      while (!stop_) {
        const int connection = accept(fd_, nullptr, nullptr);
        if (connection >= 0) {
          ++accepted_;
          close(connection);
        }
      }
    });
  }
  ~ClosingListener() {
    stop_ = true;
    shutdown(fd_, SHUT_RDWR);
    close(fd_);
    thread_.join();
  }
  std::string address() const { return absl::StrCat("127.0.0.1:", port_); }
  int accepted() const { return accepted_; }

 private:
  int fd_ = -1;
  int port_ = 0;
  std::atomic<bool> stop_{false};
  std::atomic<int> accepted_{0};
  std::thread thread_;
};

// A free loopback port where nothing listens (a replica that was killed).
std::string DeadAddress() {
  std::unique_ptr<server::Server> gone = StartServer();
  const std::string address = AddressOf(*gone);
  gone.reset();
  return address;
}

TEST(ReplicasTest, ParsesListsAndDnsNames) {
  absl::StatusOr<std::vector<std::string>> list =
      client::ResolveReplicas("127.0.0.1:1, [::1]:2,127.0.0.1:1");
  ASSERT_TRUE(list.ok()) << list.status();
  EXPECT_EQ(*list, (std::vector<std::string>{"127.0.0.1:1", "[::1]:2"}));
  EXPECT_TRUE(client::NamesReplicas("a:1,b:2"));
  EXPECT_TRUE(client::NamesReplicas("dns:///localhost:5"));
  EXPECT_FALSE(client::NamesReplicas("localhost:5"));
  for (const char* bad : {"a:1,,b:2", "a:1,b", "a:0", "dns:///localhost"}) {
    EXPECT_EQ(client::ResolveReplicas(bad).status().code(), absl::StatusCode::kInvalidArgument)
        << bad;
  }
  absl::StatusOr<std::vector<std::string>> dns = client::ResolveReplicas("dns:///localhost:5");
  ASSERT_TRUE(dns.ok()) << dns.status();
  ASSERT_FALSE(dns->empty());
  for (const std::string& address : *dns) EXPECT_THAT(address, ::testing::EndsWith(":5"));
  EXPECT_EQ(client::ResolveReplicas("dns:///no-such-host.invalid:5").status().code(),
            absl::StatusCode::kNotFound);

  std::optional<client::SplitJobId> split = client::SplitReplicaJobId("[::1]:7/job-000003");
  ASSERT_TRUE(split.has_value());
  EXPECT_EQ(split->replica, "[::1]:7");
  EXPECT_EQ(split->job_id, "job-000003");
  EXPECT_EQ(client::ReplicaJobId(split->replica, split->job_id), "[::1]:7/job-000003");
  EXPECT_FALSE(client::SplitReplicaJobId("job-000003").has_value());
  EXPECT_FALSE(client::SplitReplicaJobId("nohost/job-1").has_value());
}

TEST(ReplicasTest, EveryJobFinishesWithASoloRunsLevelsWhenReplicasAreGone) {
  std::unique_ptr<server::Server> a = StartServer(), c = StartServer();
  ASSERT_TRUE(a && c);
  const std::string bytes = *EncodeMeshToDraco(testing::Grid(30));
  absl::StatusOr<client::JobResult> solo =
      client::RunJob(client::Connect(AddressOf(*a)), MeshSpec(), bytes);
  ASSERT_TRUE(solo.ok()) << solo.status();

  ClosingListener closing;
  const std::vector<std::string> replicas = {closing.address(), DeadAddress(), AddressOf(*a),
                                             AddressOf(*c)};
  // In the order given: the two gone replicas are tried first, and skipped.
  client::ReplicaOptions in_order;
  in_order.in_order = true;
  std::vector<std::string> retried;
  in_order.on_retry = [&](const std::string& replica, const absl::Status& status) {
    EXPECT_EQ(status.code(), absl::StatusCode::kUnavailable) << status;
    retried.push_back(replica);
  };
  std::string used;
  absl::StatusOr<client::JobResult> result =
      client::RunJobOnReplicas(replicas, MeshSpec(), bytes, {}, in_order, &used);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_EQ(used, AddressOf(*a));
  EXPECT_EQ(retried, (std::vector<std::string>{replicas[0], replicas[1]}));
  EXPECT_GT(closing.accepted(), 0);
  ExpectSameHierarchy(result->hierarchy, solo->hierarchy);

  // A batch at once, the least loaded first: every job finishes, on the live replicas.
  constexpr int kJobs = 6;
  std::vector<absl::StatusOr<client::JobResult>> results(kJobs);
  std::vector<std::string> where(kJobs);
  std::vector<std::thread> clients;
  for (int i = 0; i < kJobs; ++i) {
    clients.emplace_back([&, i] {
      results[i] = client::RunJobOnReplicas(replicas, MeshSpec(), bytes, {}, {}, &where[i]);
    });
  }
  for (std::thread& thread : clients) thread.join();
  for (int i = 0; i < kJobs; ++i) {
    ASSERT_TRUE(results[i].ok()) << results[i].status();
    EXPECT_TRUE(where[i] == AddressOf(*a) || where[i] == AddressOf(*c)) << where[i];
    ExpectSameHierarchy(results[i]->hierarchy, solo->hierarchy);
  }

  // No replica left: UNAVAILABLE naming each.
  const std::vector<std::string> gone = {closing.address(), replicas[1]};
  absl::Status none = client::RunJobOnReplicas(gone, MeshSpec(), bytes, {}, {}, &used).status();
  EXPECT_EQ(none.code(), absl::StatusCode::kUnavailable);
  EXPECT_THAT(none.message(), HasSubstr("no replica accepted the job"));
  EXPECT_THAT(none.message(), HasSubstr(replicas[1]));
}

TEST(ReplicasTest, ADeadlineHitOnOneReplicaEndsTheJobThere) {
  std::unique_ptr<server::Server> a = StartServer();
  ASSERT_TRUE(a);
  // A replica that never answers: the kernel completes the TCP handshake, nobody speaks.
  int silent_port = 0;
  const int silent = testing::ListenOnLoopback(8, silent_port);
  ASSERT_GE(silent, 0);
  const std::string silent_address = absl::StrCat("127.0.0.1:", silent_port);

  client::ReplicaOptions in_order;
  in_order.in_order = true;
  client::RunOptions run;
  run.deadline = absl::Milliseconds(500);
  std::string used;
  const std::string bytes = *EncodeMeshToDraco(testing::Grid(10));
  absl::Status status = client::RunJobOnReplicas({silent_address, AddressOf(*a)}, MeshSpec(), bytes,
                                                 run, in_order, &used)
                            .status();
  close(silent);
  // DEADLINE_EXCEEDED is no reason to try another replica: the job is not sent to A.
  EXPECT_EQ(status.code(), absl::StatusCode::kDeadlineExceeded) << status;
  EXPECT_EQ(used, silent_address);
  absl::StatusOr<v1::JobList> jobs = client::ListJobs(client::Connect(AddressOf(*a)));
  ASSERT_TRUE(jobs.ok()) << jobs.status();
  EXPECT_EQ(jobs->jobs_size(), 0);
}

TEST(ReplicasTest, DetachedIdNamesItsReplicaAndAGoneReplicaIsReportedClearly) {
  std::unique_ptr<server::Server> a = StartServer();
  ASSERT_TRUE(a);
  const std::string dead = DeadAddress();
  const std::string bytes = *EncodeMeshToDraco(testing::Grid(20));
  client::ReplicaOptions in_order;
  in_order.in_order = true;
  std::string used;
  absl::StatusOr<v1::Accepted> accepted = client::SubmitDetachedOnReplicas(
      {dead, AddressOf(*a)}, MeshSpec(), bytes, {}, in_order, &used);
  ASSERT_TRUE(accepted.ok()) << accepted.status();
  EXPECT_EQ(used, AddressOf(*a));
  std::optional<client::SplitJobId> split = client::SplitReplicaJobId(accepted->job_id());
  ASSERT_TRUE(split.has_value()) << accepted->job_id();
  EXPECT_EQ(split->replica, AddressOf(*a));
  absl::StatusOr<client::JobResult> watched =
      client::WatchJob(client::Connect(split->replica), split->job_id);
  ASSERT_TRUE(watched.ok()) << watched.status();

  // The replica that holds the job goes away: the watch says so.
  const std::string address = AddressOf(*a);
  a.reset();
  client::WatchOptions quick;
  quick.max_resumes = 1;
  quick.resume_delay = absl::Milliseconds(50);
  absl::Status status =
      client::WatchJob(client::Connect(split->replica), split->job_id, quick).status();
  status = client::ExplainReplicaFailure(status, split->replica, split->job_id);
  EXPECT_EQ(status.code(), absl::StatusCode::kUnavailable) << status;
  EXPECT_THAT(status.message(), HasSubstr(absl::StrCat("replica ", address)));
  EXPECT_THAT(status.message(), HasSubstr("Submit the job again"));
}

// Every level the same: cluster count, energy and every triplet.
void ExpectIdenticalLevels(const HierarchyLog& a, const HierarchyLog& b) {
  ASSERT_EQ(a.num_levels(), b.num_levels());
  ASSERT_TRUE(std::ranges::equal(a.start_labels(), b.start_labels()));
  for (size_t level = 1; level < a.num_levels(); ++level) {
    const LevelMoves x = a.level(level), y = b.level(level);
    ASSERT_EQ(x.cluster_count, y.cluster_count) << "level " << level;
    ASSERT_EQ(x.energy, y.energy) << "level " << level;
    ASSERT_TRUE(std::ranges::equal(x.element, y.element)) << "level " << level;
    ASSERT_TRUE(std::ranges::equal(x.to_cluster, y.to_cluster)) << "level " << level;
    ASSERT_TRUE(std::ranges::equal(x.from_cluster, y.from_cluster)) << "level " << level;
  }
}

// The job numbers of the levels on_event was given, in order, each once per level (the
// pieces of a split level count once).
class LevelNumbers {
 public:
  void Take(const v1::JobEvent& event) {
    if (event.has_snapshot() && event.snapshot().first_element() == 0) {
      numbers_.push_back(event.snapshot().level());
    }
    if (!event.has_levels()) return;
    const v1::LevelBatch& batch = event.levels();
    for (int i = 0; i < batch.cluster_count_size(); ++i) {
      if (!(i == 0 && continuing_)) numbers_.push_back(batch.first_level() + i);
    }
    if (batch.cluster_count_size() > 0) continuing_ = batch.last_level_continues();
  }
  const std::vector<uint64_t>& numbers() const { return numbers_; }

 private:
  std::vector<uint64_t> numbers_;
  bool continuing_ = false;
};

std::vector<uint64_t> ZeroTo(size_t n) {
  std::vector<uint64_t> out(n);
  for (size_t i = 0; i < n; ++i) out[i] = i;
  return out;
}

std::unique_ptr<server::Server> StartServerWithSmallEvents() {
  server::ServerOptions options;
  options.gpu = server::GpuMode::kOff;
  options.max_event_bytes = 16 << 10;  // split snapshots and levels: many events
  return testing::StartServer(options);
}

constexpr size_t kCutAfter = 100 << 10;  // of a ~400 KB stream (HC on a 60x60 grid)

v1::JobSpec HcSpec() { return testing::MeshSpec(v1::ALGORITHM_HC, 0, "replicas_test"); }

// The replica that accepted the job is cut off in the middle of its levels and never
// answers again (a SIGKILLed process): the job is submitted to the next replica, the
// levels received are kept, the new stream's repeats are checked and not passed on again,
// and the result equals a solo run's, level by level.
TEST(ReplicasTest, AJobWhoseReplicaIsLostMidJobIsSubmittedAgainAndEqualsASoloRun) {
  std::unique_ptr<server::Server> a = StartServerWithSmallEvents(), b = StartServer();
  ASSERT_TRUE(a && b);
  const std::string bytes = *EncodeMeshToDraco(testing::Grid(60));  // 7,200 faces
  absl::StatusOr<client::JobResult> solo =
      client::RunJob(client::Connect(AddressOf(*b)), HcSpec(), bytes);
  ASSERT_TRUE(solo.ok()) << solo.status();

  CuttingProxy lost(a->port(), kCutAfter, CuttingProxy::AfterCut::kRefuse);
  client::ReplicaOptions in_order;
  in_order.in_order = true;
  std::vector<client::Resubmission> resubmissions;
  in_order.on_resubmit = [&](const client::Resubmission& r) { resubmissions.push_back(r); };
  LevelNumbers passed_on;
  client::RunOptions run;
  run.on_event = [&](const v1::JobEvent& event) { passed_on.Take(event); };
  std::string used;
  absl::StatusOr<client::JobResult> result = client::RunJobOnReplicas(
      {lost.address(), AddressOf(*b)}, HcSpec(), bytes, run, in_order, &used);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_EQ(used, AddressOf(*b));
  ASSERT_EQ(resubmissions.size(), 1u);
  EXPECT_EQ(resubmissions[0].lost_replica, lost.address());
  EXPECT_EQ(resubmissions[0].attempt, 1);
  EXPECT_EQ(resubmissions[0].max_resubmits, 2);
  EXPECT_TRUE(client::IsBrokenStream(resubmissions[0].status)) << resubmissions[0].status;
  // Levels had arrived from the lost replica, not all of them.
  EXPECT_GT(resubmissions[0].levels_kept, 1u);
  EXPECT_LT(resubmissions[0].levels_kept, solo->hierarchy.num_levels());
  ExpectIdenticalLevels(result->hierarchy, solo->hierarchy);
  // on_event saw each level once, in order, over both streams.
  EXPECT_EQ(passed_on.numbers(), ZeroTo(solo->hierarchy.num_levels()));
  absl::StatusOr<v1::JobList> on_b = client::ListJobs(client::Connect(AddressOf(*b)));
  ASSERT_TRUE(on_b.ok()) << on_b.status();
  EXPECT_EQ(on_b->jobs_size(), 2);  // the solo run and the resubmitted job
}

// Every replica loses the job: the tries are bounded, and the message names them.
TEST(ReplicasTest, ResubmissionsAreBounded) {
  std::unique_ptr<server::Server> a = StartServerWithSmallEvents();
  ASSERT_TRUE(a);
  const std::string bytes = *EncodeMeshToDraco(testing::Grid(60));
  for (int limit : {0, 1}) {
    CuttingProxy first(a->port(), kCutAfter, CuttingProxy::AfterCut::kRefuse);
    CuttingProxy second(a->port(), kCutAfter, CuttingProxy::AfterCut::kRefuse);
    client::ReplicaOptions options;
    options.in_order = true;
    options.max_resubmits = limit;
    int resubmits = 0;
    options.on_resubmit = [&](const client::Resubmission&) { ++resubmits; };
    absl::Status status = client::RunJobOnReplicas({first.address(), second.address()}, HcSpec(),
                                                   bytes, {}, options, nullptr)
                              .status();
    EXPECT_EQ(status.code(), absl::StatusCode::kUnavailable) << status;
    EXPECT_EQ(resubmits, limit);
    EXPECT_THAT(status.message(), HasSubstr(absl::StrCat("the limit (--resubmit ", limit, ")")));
    EXPECT_THAT(status.message(), HasSubstr(first.address()));
    EXPECT_EQ(second.connections(), limit) << "limit " << limit;
  }
}

// A job cancelled on its replica ended there: it is not submitted again.
TEST(ReplicasTest, AJobCancelledOnItsReplicaIsNotSubmittedAgain) {
  std::unique_ptr<server::Server> a = StartServer(), b = StartServer();
  ASSERT_TRUE(a && b);
  const std::string bytes = *EncodeMeshToDraco(testing::Grid(60));
  client::ReplicaOptions in_order;
  in_order.in_order = true;
  int resubmits = 0;
  in_order.on_resubmit = [&](const client::Resubmission&) { ++resubmits; };
  client::RunOptions run;
  run.on_event = [&](const v1::JobEvent& event) {
    if (event.has_accepted()) {
      ASSERT_TRUE(
          client::CancelJob(client::Connect(AddressOf(*a)), event.accepted().job_id()).ok());
    }
  };
  absl::Status status = client::RunJobOnReplicas({AddressOf(*a), AddressOf(*b)}, HcSpec(), bytes,
                                                 run, in_order, nullptr)
                            .status();
  EXPECT_EQ(status.code(), absl::StatusCode::kCancelled) << status;
  EXPECT_EQ(resubmits, 0);
  absl::StatusOr<v1::JobList> on_b = client::ListJobs(client::Connect(AddressOf(*b)));
  ASSERT_TRUE(on_b.ok()) << on_b.status();
  EXPECT_EQ(on_b->jobs_size(), 0);
}

// A replica that sends other levels than those received fails the job loudly, naming the
// level: here another energy (planar, the same start at energy 0), which differs at level 1.
TEST(ReplicasTest, AReplicaWithOtherLevelsFailsTheJob) {
  std::unique_ptr<server::Server> a = StartServerWithSmallEvents(), b = StartServer();
  ASSERT_TRUE(a && b);
  const std::string bytes = *EncodeMeshToDraco(testing::Grid(60));
  client::ReceivedLevels received;
  CuttingProxy lost(a->port(), kCutAfter, CuttingProxy::AfterCut::kRefuse);
  client::RunOptions run;
  run.received = &received;
  ASSERT_FALSE(client::RunJob(client::Connect(lost.address()), HcSpec(), bytes, run).ok());
  ASSERT_GT(received.levels(), 1u);
  v1::JobSpec planar = HcSpec();
  planar.set_energy(v1::ENERGY_PLANAR);
  absl::Status status = client::RunJob(client::Connect(AddressOf(*b)), planar, bytes, run).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kDataLoss) << status;
  EXPECT_THAT(std::string(status.message()),
              HasSubstr("level 1 differs from the one received before (it has 7199 clusters"));
}

// Detached: the replica holding the job is lost in the middle of a watch; the client kept
// the spec and input (the documented rule), WatchOnReplicas submits the job again to the
// next replica and watches it there: the levels equal a solo run's, the id names the new
// replica.
TEST(ReplicasTest, ADetachedJobLostWithItsReplicaIsSubmittedAgainByWatchOnReplicas) {
  std::unique_ptr<server::Server> a = StartServerWithSmallEvents(), b = StartServer();
  ASSERT_TRUE(a && b);
  const std::string bytes = *EncodeMeshToDraco(testing::Grid(60));
  absl::StatusOr<client::JobResult> solo =
      client::RunJob(client::Connect(AddressOf(*b)), HcSpec(), bytes);
  ASSERT_TRUE(solo.ok()) << solo.status();
  absl::StatusOr<v1::Accepted> accepted =
      client::SubmitDetached(client::Connect(AddressOf(*a)), HcSpec(), bytes);
  ASSERT_TRUE(accepted.ok()) << accepted.status();
  // Replica "A" as the client knows it: the address of a connection that is cut in the
  // middle of the watch and never answers again.
  CuttingProxy lost(a->port(), kCutAfter, CuttingProxy::AfterCut::kRefuse);
  const std::string id = client::ReplicaJobId(lost.address(), accepted->job_id());
  client::WatchOptions watch;
  watch.max_resumes = 1;
  watch.resume_delay = absl::Milliseconds(20);
  LevelNumbers passed_on;
  watch.on_event = [&](const v1::JobEvent& event) { passed_on.Take(event); };
  client::ReplicaOptions options;
  std::vector<client::Resubmission> resubmissions;
  options.on_resubmit = [&](const client::Resubmission& r) { resubmissions.push_back(r); };
  std::string final_id;
  absl::StatusOr<client::JobResult> result = client::WatchOnReplicas(
      {lost.address(), AddressOf(*b)}, id, HcSpec(), bytes, watch, options, &final_id);
  ASSERT_TRUE(result.ok()) << result.status();
  ASSERT_EQ(resubmissions.size(), 1u);
  EXPECT_EQ(resubmissions[0].lost_replica, lost.address());
  EXPECT_GT(resubmissions[0].levels_kept, 1u);
  std::optional<client::SplitJobId> split = client::SplitReplicaJobId(final_id);
  ASSERT_TRUE(split.has_value()) << final_id;
  EXPECT_EQ(split->replica, AddressOf(*b));
  EXPECT_EQ(result->job_id, final_id);
  ExpectIdenticalLevels(result->hierarchy, solo->hierarchy);
  EXPECT_EQ(passed_on.numbers(), ZeroTo(solo->hierarchy.num_levels()));

  // A replica that answers and does not hold the job (NOT_FOUND) ends the watch as it is.
  absl::Status gone =
      client::WatchOnReplicas({AddressOf(*b)}, client::ReplicaJobId(AddressOf(*b), "no-such-job"),
                              HcSpec(), bytes, {}, options, nullptr)
          .status();
  EXPECT_EQ(gone.code(), absl::StatusCode::kNotFound) << gone;
  EXPECT_EQ(resubmissions.size(), 1u);
}

grpc::health::v1::HealthCheckResponse::ServingStatus Readiness(const server::Server& server) {
  auto stub = grpc::health::v1::Health::NewStub(client::Connect(AddressOf(server)));
  grpc::ClientContext context;
  grpc::health::v1::HealthCheckRequest request;
  request.set_service("mlclust.v1.Clustering");
  grpc::health::v1::HealthCheckResponse response;
  EXPECT_TRUE(stub->Check(&context, request, &response).ok());
  return response.status();
}

// Readiness (the health service's mlclust.v1.Clustering, docker/k8s's readinessProbe; GET
// /ready on the metrics port for probes without gRPC or TLS) follows the server's own
// state: NOT_SERVING while its queue is full, SERVING when it has room again; the overall
// service (liveness) stays SERVING.
TEST(ReplicasTest, ReadinessFollowsAFullQueue) {
  server::ServerOptions options;
  options.gpu = server::GpuMode::kOff;
  options.queue_capacity = 1;
  options.metrics_address = "127.0.0.1:0";
  std::unique_ptr<server::Server> a = testing::StartServer(options);
  ASSERT_TRUE(a);
  auto channel = client::Connect(AddressOf(*a));
  using Health = grpc::health::v1::HealthCheckResponse;
  EXPECT_EQ(Readiness(*a), Health::SERVING);
  EXPECT_THAT(testing::HttpGet(a->metrics_port(), "/ready"), HasSubstr("200 OK"));
  // One job runs (seconds of HC on 320,000 faces), one waits: the queue is full.
  absl::StatusOr<v1::Accepted> running =
      client::SubmitDetached(channel, HcSpec(), *EncodeMeshToDraco(testing::Grid(400)));
  ASSERT_TRUE(running.ok()) << running.status();
  for (int i = 0; i < 600; ++i) {
    absl::StatusOr<v1::JobList> jobs = client::ListJobs(channel);
    ASSERT_TRUE(jobs.ok()) << jobs.status();
    if (jobs->jobs(0).state() == "running") break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  absl::StatusOr<v1::Accepted> waiting =
      client::SubmitDetached(channel, HcSpec(), *EncodeMeshToDraco(testing::Grid(10)));
  ASSERT_TRUE(waiting.ok()) << waiting.status();
  EXPECT_EQ(Readiness(*a), Health::NOT_SERVING);
  const std::string full = testing::HttpGet(a->metrics_port(), "/ready");
  EXPECT_THAT(full, HasSubstr("503"));
  EXPECT_THAT(full, HasSubstr("not ready: the job queue is full"));
  {
    auto stub = grpc::health::v1::Health::NewStub(channel);
    grpc::ClientContext context;
    grpc::health::v1::HealthCheckResponse overall;
    ASSERT_TRUE(stub->Check(&context, grpc::health::v1::HealthCheckRequest(), &overall).ok());
    EXPECT_EQ(overall.status(), Health::SERVING);
  }
  ASSERT_TRUE(client::CancelJob(channel, waiting->job_id()).ok());
  EXPECT_EQ(Readiness(*a), Health::SERVING);
  EXPECT_THAT(testing::HttpGet(a->metrics_port(), "/ready"), HasSubstr("200 OK"));
  ASSERT_TRUE(client::CancelJob(channel, running->job_id()).ok());
}

}  // namespace
}  // namespace mlclust
