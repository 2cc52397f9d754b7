// Several servers behind one client (client/replicas.h) on loopback: a replica that is
// gone or that drops connections before accepting a job is skipped, every job finishes
// with the levels of a solo run, a detached job's id names its replica, and a replica gone
// after accepting a job fails it clearly without submitting it again.
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
#include "server/server.h"
#include "tests/fixtures/loopback.h"
#include "tests/fixtures/test_meshes.h"
#include "tests/fixtures/test_server.h"

namespace mlclust {
namespace {

using ::testing::HasSubstr;

using testing::AddressOf;
using testing::ExpectSameHierarchy;

std::unique_ptr<server::Server> StartServer() {
  server::ServerOptions options;
  options.gpu = server::GpuMode::kOff;
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
  EXPECT_THAT(status.message(), HasSubstr("never moved to another replica"));
}

}  // namespace
}  // namespace mlclust
