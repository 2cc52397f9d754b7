// The service under clients that misbehave or are limited: split messages for default-limit
// clients, a reader that stops reading, admission, workers, drain.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <thread>

#include "client/client.h"
#include "core/io/draco_codec.h"
#include "grpcpp/grpcpp.h"
#include "mlclust/v1/mlclust.grpc.pb.h"
#include "server/server.h"
#include "tests/fixtures/test_meshes.h"

namespace mlclust {
namespace {

using ::testing::HasSubstr;

std::unique_ptr<server::Server> StartServer(server::ServerOptions options) {
  options.listen_address = "127.0.0.1:0";
  options.log = false;
  absl::StatusOr<std::unique_ptr<server::Server>> started = server::Server::Start(options);
  EXPECT_TRUE(started.ok()) << started.status();
  return started.ok() ? *std::move(started) : nullptr;
}

std::shared_ptr<grpc::Channel> LimitedChannel(int port, int max_receive_bytes) {
  grpc::ChannelArguments arguments;
  arguments.SetMaxReceiveMessageSize(max_receive_bytes);
  return grpc::CreateCustomChannel(absl::StrCat("127.0.0.1:", port),
                                   grpc::InsecureChannelCredentials(), arguments);
}

v1::JobSpec MeshSpec(v1::Algorithm algorithm, uint32_t clusters = 0) {
  v1::JobSpec spec;
  spec.set_input_kind(v1::INPUT_KIND_DRACO_MESH);
  spec.set_algorithm(algorithm);
  spec.set_energy(v1::ENERGY_CVD);
  spec.set_clusters(clusters);
  return spec;
}

v1::Stats GetStats(const std::shared_ptr<grpc::Channel>& channel) {
  auto stub = v1::Clustering::NewStub(channel);
  grpc::ClientContext context;
  v1::Stats stats;
  EXPECT_TRUE(stub->GetStats(&context, v1::GetStatsRequest(), &stats).ok());
  return stats;
}

void ExpectSameHierarchy(const HierarchyLog& a, const HierarchyLog& b) {
  ASSERT_EQ(a.num_levels(), b.num_levels());
  ASSERT_EQ(a.num_moves(), b.num_moves());
  for (size_t level = 0; level < a.num_levels(); ++level) {
    ASSERT_EQ(a.cluster_count(level), b.cluster_count(level)) << "level " << level;
    ASSERT_EQ(a.energy(level), b.energy(level)) << "level " << level;
  }
  for (size_t level : {size_t{0}, a.num_levels() / 2, a.num_levels() - 1}) {
    EXPECT_EQ(*a.LabelsAt(level), *b.LabelsAt(level)) << "level " << level;
  }
}

// Messages are split under the server's max_event_bytes (3 MiB by default, under gRPC's
// default 4 MiB); here 16 KiB against a client that accepts no more than 20 KiB, so a
// hierarchy and a single-level result both need split snapshots and split levels.
TEST(SplitMessagesTest, AClientWithSmallLimitsRebuildsTheSameLevels) {
  std::unique_ptr<server::Server> reference = StartServer({});
  server::ServerOptions small;
  small.max_event_bytes = 16 << 10;
  std::unique_ptr<server::Server> splitting = StartServer(small);
  ASSERT_TRUE(reference && splitting);
  auto reference_channel = client::Connect(absl::StrCat("127.0.0.1:", reference->port()));
  auto limited_channel = LimitedChannel(splitting->port(), 20 << 10);
  const std::string bytes = *EncodeMeshToDraco(testing::Grid(100));  // 20,000 faces
  for (const v1::JobSpec& spec : {MeshSpec(v1::ALGORITHM_HC), MeshSpec(v1::ALGORITHM_EMLO, 40)}) {
    absl::StatusOr<client::JobResult> expected = client::RunJob(reference_channel, spec, bytes);
    ASSERT_TRUE(expected.ok()) << expected.status();
    if (spec.algorithm() == v1::ALGORITHM_HC) {
      // Unsplit, the hierarchy's batches are too big for the limited client.
      absl::StatusOr<client::JobResult> too_big =
          client::RunJob(LimitedChannel(reference->port(), 20 << 10), spec, bytes);
      EXPECT_EQ(too_big.status().code(), absl::StatusCode::kResourceExhausted);
    }
    absl::StatusOr<client::JobResult> split = client::RunJob(limited_channel, spec, bytes);
    ASSERT_TRUE(split.ok()) << split.status();
    ExpectSameHierarchy(expected->hierarchy, split->hierarchy);
    EXPECT_EQ(split->done.triplets(), expected->done.triplets());
  }
}

// The probe's finding: a client that stops reading held the single worker as long as it
// stayed connected. Now its job is cut off at its budget and the next job runs.
TEST(StalledReaderTest, IsCutOffAtItsBudgetAndTheWorkerMovesOn) {
  server::ServerOptions options;
  options.result_job_budget_bytes = 1 << 20;
  options.gpu = server::GpuMode::kOff;
  std::unique_ptr<server::Server> server = StartServer(options);
  ASSERT_TRUE(server);
  auto channel = client::Connect(absl::StrCat("127.0.0.1:", server->port()));
  const std::string big = *EncodeMeshToDraco(testing::Grid(400));  // 320k faces

  auto stub = v1::Clustering::NewStub(channel);
  grpc::ClientContext stalled_context;
  stalled_context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(300));
  auto stalled = stub->Run(&stalled_context);
  v1::RunRequest request;
  *request.mutable_spec() = MeshSpec(v1::ALGORITHM_HC);
  request.mutable_spec()->set_input_bytes(big.size());
  request.set_chunk(big);
  ASSERT_TRUE(stalled->Write(request));
  stalled->WritesDone();
  v1::JobEvent event;
  ASSERT_TRUE(stalled->Read(&event));
  ASSERT_TRUE(event.has_accepted());
  // ... and reads nothing more. The next job still runs (it would wait for ever before).
  client::RunOptions run_options;
  run_options.deadline = absl::Seconds(120);
  absl::StatusOr<client::JobResult> next = client::RunJob(
      channel, MeshSpec(v1::ALGORITHM_HC), *EncodeMeshToDraco(testing::Grid(10)), run_options);
  ASSERT_TRUE(next.ok()) << next.status();
  const v1::Stats stats = GetStats(channel);
  EXPECT_EQ(stats.readers_cut_off(), 1u);
  EXPECT_EQ(stats.jobs_succeeded(), 1u);
  EXPECT_EQ(stats.result_bytes_held(), 0u);
  // When the stalled client reads again it learns why its stream ended.
  v1::JobEvent last;
  while (stalled->Read(&event)) last = event;
  EXPECT_TRUE(last.final());
  EXPECT_EQ(last.failed().code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  const grpc::Status status = stalled->Finish();
  EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(status.error_message(), HasSubstr("read too slowly"));
}

}  // namespace
}  // namespace mlclust
