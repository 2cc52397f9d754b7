// The service under clients that misbehave or are limited: split messages for default-limit
// clients, a reader that stops reading, admission, workers, drain.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <future>
#include <thread>

#include "absl/strings/match.h"
#include "client/client.h"
#include "core/io/draco_codec.h"
#include "google/protobuf/struct.pb.h"
#include "google/protobuf/util/json_util.h"
#include "grpcpp/grpcpp.h"
#include "mlclust/v1/mlclust.grpc.pb.h"
#include "server/log.h"
#include "server/server.h"
#include "tests/fixtures/capture_stderr.h"
#include "tests/fixtures/test_meshes.h"
#include "tests/fixtures/test_server.h"

namespace mlclust {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

using testing::ExpectSameHierarchy;
using testing::GetStats;
using testing::MeshSpec;
using testing::StartServer;

std::shared_ptr<grpc::Channel> LimitedChannel(int port, int max_receive_bytes) {
  grpc::ChannelArguments arguments;
  arguments.SetMaxReceiveMessageSize(max_receive_bytes);
  return grpc::CreateCustomChannel(absl::StrCat("127.0.0.1:", port),
                                   grpc::InsecureChannelCredentials(), arguments);
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
// stayed connected. Now its call is cut off at its budget, its job runs on for Watch, and
// the next job runs.
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
  const std::string id = event.accepted().job_id();
  // ... and reads nothing more. The next job still runs (it would wait for ever before).
  client::RunOptions run_options;
  run_options.deadline = absl::Seconds(120);
  absl::StatusOr<client::JobResult> next = client::RunJob(
      channel, MeshSpec(v1::ALGORITHM_HC), *EncodeMeshToDraco(testing::Grid(10)), run_options);
  ASSERT_TRUE(next.ok()) << next.status();
  const v1::Stats stats = GetStats(channel);
  EXPECT_EQ(stats.readers_cut_off(), 1u);
  // Issue 24, item 6: the cut-off reader's job is not cancelled (it was, at 94% done): it
  // runs on where its record keeps its levels, and ends succeeded before the next one.
  EXPECT_EQ(stats.jobs_succeeded(), 2u);
  EXPECT_EQ(stats.jobs_cancelled(), 0u);
  EXPECT_EQ(stats.result_bytes_held(), 0u);
  // When the stalled client reads again it learns why its stream ended, and to watch.
  v1::JobEvent last;
  while (stalled->Read(&event)) last = event;
  EXPECT_TRUE(last.final());
  EXPECT_EQ(last.failed().code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  const grpc::Status status = stalled->Finish();
  EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(status.error_message(), HasSubstr("read too slowly"));
  EXPECT_THAT(status.error_message(), HasSubstr("the job runs on and keeps its levels"));
  EXPECT_THAT(status.error_message(), HasSubstr(absl::StrCat("mlclust watch ", id)));
  // And watching gives the whole hierarchy.
  client::WatchOptions watch_options;
  watch_options.from_level = 319990;  // the last levels of 320,000 faces
  absl::StatusOr<client::JobResult> watched = client::WatchJob(channel, id, watch_options);
  ASSERT_TRUE(watched.ok()) << watched.status();
  EXPECT_EQ(watched->done.levels(), 320000u);
}

}  // namespace
}  // namespace mlclust

namespace mlclust {
namespace {

// A call that sends a spec (and maybe some input) and then waits, like a stalled upload.
struct StalledCall {
  grpc::ClientContext context;
  std::unique_ptr<grpc::ClientReaderWriter<v1::RunRequest, v1::JobEvent>> stream;
};

std::unique_ptr<StalledCall> StartStalledCall(v1::Clustering::Stub& stub, uint64_t declared,
                                              const std::string& sent) {
  auto call = std::make_unique<StalledCall>();
  call->context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(120));
  call->stream = stub.Run(&call->context);
  v1::RunRequest request;
  *request.mutable_spec() = MeshSpec(v1::ALGORITHM_HC);
  request.mutable_spec()->set_input_bytes(declared);
  request.set_chunk(sent);
  call->stream->Write(request);
  return call;
}

// Reads a refused call's answer: its Failed event's code and the call's status.
grpc::Status ReadToEnd(StalledCall& call) {
  v1::JobEvent event;
  while (call.stream->Read(&event)) {
  }
  return call.stream->Finish();
}

TEST(AdmissionTest, CallsPerConnectionAreBoundedAndSpecsReserveNothing) {
  server::ServerOptions options;
  options.max_calls_per_connection = 4;
  std::unique_ptr<server::Server> server = StartServer(options);
  ASSERT_TRUE(server);
  auto channel = client::Connect(absl::StrCat("127.0.0.1:", server->port()));
  auto stub = v1::Clustering::NewStub(channel);
  // Spec-only calls declaring 256 MiB each: 4 wait for their data, the rest are refused.
  // Each of the first 4 is admitted before the next starts: calls started together can
  // reach the server in any order, and a refused one among the first 4 would leave a later
  // one waiting for data that never comes.
  std::vector<std::unique_ptr<StalledCall>> calls;
  for (int i = 0; i < 10; ++i) {
    calls.push_back(StartStalledCall(*stub, uint64_t{256} << 20, ""));
    for (int wait = 0;
         i < 4 && wait < 1000 && GetStats(channel).calls_active() <= static_cast<uint64_t>(i);
         ++wait) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }
  int refused = 0;
  for (int i = 4; i < 10; ++i) {
    const grpc::Status status = ReadToEnd(*calls[i]);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
    EXPECT_THAT(status.error_message(), HasSubstr("per connection"));
    ++refused;
  }
  v1::Stats stats = GetStats(channel);
  EXPECT_EQ(stats.calls_refused(), 6u);
  EXPECT_EQ(stats.calls_active(), 4u);
  EXPECT_EQ(stats.upload_bytes_in_flight(), 0u);  // declared, not received: nothing held
  for (int i = 0; i < 4; ++i) calls[i]->context.TryCancel();
  for (int i = 0; i < 4; ++i) ReadToEnd(*calls[i]);
  // The slots come back.
  for (int i = 0; i < 200 && GetStats(channel).calls_active() > 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  EXPECT_EQ(GetStats(channel).calls_active(), 0u);
  EXPECT_TRUE(
      client::RunJob(channel, MeshSpec(v1::ALGORITHM_HC), *EncodeMeshToDraco(testing::Grid(5)))
          .ok());
}

// Issue 24, item 1: stalled calls used to hold their admission slots for ever (64 of them
// locked every other local client out). An upload that receives nothing for the idle
// timeout is ended with DEADLINE_EXCEEDED saying so, a call that never sends its spec too,
// and the slots come back for everyone else.
TEST(UploadTimeoutTest, StalledUploadsAndSilentCallsAreEndedAndTheirSlotsComeBack) {
  server::ServerOptions options;
  options.upload_idle_timeout = absl::Milliseconds(300);
  options.max_calls_per_peer = 4;
  std::unique_ptr<server::Server> server = StartServer(options);
  ASSERT_TRUE(server);
  auto channel = client::Connect(absl::StrCat("127.0.0.1:", server->port()));
  auto stub = v1::Clustering::NewStub(channel);
  std::vector<std::unique_ptr<StalledCall>> calls;
  for (int i = 0; i < 3; ++i) calls.push_back(StartStalledCall(*stub, 1 << 20, "x"));
  // One call that sends nothing at all, not even its spec.
  auto silent = std::make_unique<StalledCall>();
  silent->context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(120));
  silent->stream = stub->Run(&silent->context);
  calls.push_back(std::move(silent));
  for (auto& call : calls) {
    const grpc::Status status = ReadToEnd(*call);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::DEADLINE_EXCEEDED);
    EXPECT_THAT(status.error_message(), HasSubstr("the upload made no progress for"));
  }
  for (int i = 0; i < 500 && GetStats(channel).calls_active() > 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  const v1::Stats stats = GetStats(channel);
  EXPECT_EQ(stats.calls_active(), 0u);
  EXPECT_EQ(stats.uploads_timed_out(), 4u);
  EXPECT_EQ(stats.upload_bytes_in_flight(), 0u);
  EXPECT_TRUE(
      client::RunJob(channel, MeshSpec(v1::ALGORITHM_HC), *EncodeMeshToDraco(testing::Grid(5)))
          .ok());
}

// A trickle that is never idle long enough for the idle timeout is ended by the minimum
// rate: a call may take idle_timeout + received / rate.
TEST(UploadTimeoutTest, AnUploadUnderTheMinimumRateIsEnded) {
  server::ServerOptions options;
  options.upload_idle_timeout = absl::Milliseconds(500);
  options.upload_min_bytes_per_second = 1 << 20;
  std::unique_ptr<server::Server> server = StartServer(options);
  ASSERT_TRUE(server);
  auto channel = client::Connect(absl::StrCat("127.0.0.1:", server->port()));
  auto stub = v1::Clustering::NewStub(channel);
  std::unique_ptr<StalledCall> call = StartStalledCall(*stub, 64 << 20, std::string(1024, 'x'));
  v1::RunRequest more;
  more.set_chunk(std::string(1024, 'x'));
  // 1 KiB every 50 ms (20 KiB/s) until the server ends the call (at most 100 s of it).
  for (int i = 0; i < 2000 && call->stream->Write(more); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  const grpc::Status status = ReadToEnd(*call);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::DEADLINE_EXCEEDED);
  EXPECT_THAT(status.error_message(), HasSubstr("the upload is too slow"));
  EXPECT_THAT(status.error_message(), HasSubstr("minimum rate of 1048576 bytes/s"));
}

TEST(UploadTimeoutTest, OptionsOutOfRangeAreRefusedAtStart) {
  server::ServerOptions options;
  options.upload_idle_timeout = absl::ZeroDuration();
  absl::StatusOr<std::unique_ptr<server::Server>> zero = testing::StartLocal(options);
  EXPECT_EQ(zero.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(zero.status().message(), HasSubstr("upload idle timeout"));
  options.upload_idle_timeout = absl::Seconds(30);
  options.upload_min_bytes_per_second = uint64_t{2} << 30;
  EXPECT_EQ(testing::StartLocal(options).status().code(), absl::StatusCode::kInvalidArgument);
}

TEST(AdmissionTest, UploadsInFlightAreBoundedBeforeTheBufferGrows) {
  server::ServerOptions options;
  options.max_upload_bytes_in_flight = 8 << 20;
  std::unique_ptr<server::Server> server = StartServer(options);
  ASSERT_TRUE(server);
  auto channel = client::Connect(absl::StrCat("127.0.0.1:", server->port()));
  auto stub = v1::Clustering::NewStub(channel);
  const std::string three_mib(3 << 20, 'x');
  std::vector<std::unique_ptr<StalledCall>> calls;
  for (int i = 0; i < 2; ++i) calls.push_back(StartStalledCall(*stub, 4 << 20, three_mib));
  // The two uploads are held (6 MiB); wait until the server has them.
  for (int i = 0; i < 200 && GetStats(channel).upload_bytes_in_flight() < (6u << 20); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  EXPECT_EQ(GetStats(channel).upload_bytes_in_flight(), 6u << 20);
  auto third = StartStalledCall(*stub, 4 << 20, three_mib);
  const grpc::Status status = ReadToEnd(*third);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(status.error_message(), HasSubstr("uploads in progress"));
  EXPECT_EQ(GetStats(channel).upload_bytes_in_flight(), 6u << 20);
  for (auto& call : calls) call->context.TryCancel();
  for (auto& call : calls) ReadToEnd(*call);
  for (int i = 0; i < 200 && GetStats(channel).upload_bytes_in_flight() > 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  EXPECT_EQ(GetStats(channel).upload_bytes_in_flight(), 0u);
  EXPECT_EQ(GetStats(channel).calls_refused(), 1u);
}

TEST(AdmissionTest, QueuedInputsAreBoundedTogether) {
  const std::string bytes = *EncodeMeshToDraco(testing::Grid(20));
  server::ServerOptions tight;
  tight.max_queued_input_bytes = bytes.size() - 1;
  std::unique_ptr<server::Server> server = StartServer(tight);
  ASSERT_TRUE(server);
  auto channel = client::Connect(absl::StrCat("127.0.0.1:", server->port()));
  absl::StatusOr<client::JobResult> refused =
      client::RunJob(channel, MeshSpec(v1::ALGORITHM_HC), bytes);
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(refused.status().message(), HasSubstr("queued jobs' inputs"));
  // Room for one input: jobs one after the other fit, the budget returns as each starts.
  server::ServerOptions one;
  one.max_queued_input_bytes = bytes.size();
  server = StartServer(one);
  channel = client::Connect(absl::StrCat("127.0.0.1:", server->port()));
  for (int i = 0; i < 3; ++i) {
    EXPECT_TRUE(client::RunJob(channel, MeshSpec(v1::ALGORITHM_HC), bytes).ok());
  }
  EXPECT_EQ(GetStats(channel).queued_input_bytes(), 0u);
}

TEST(AdmissionTest, AnUnknownInputKindIsRefusedBeforeQueueing) {
  std::unique_ptr<server::Server> server = StartServer({});
  auto channel = client::Connect(absl::StrCat("127.0.0.1:", server->port()));
  v1::JobSpec spec = MeshSpec(v1::ALGORITHM_HC);
  spec.set_input_kind(static_cast<v1::InputKind>(7));
  absl::StatusOr<client::JobResult> result = client::RunJob(channel, spec, "0123456789");
  EXPECT_EQ(result.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(result.status().message(), HasSubstr("input_kind 7"));
  const v1::Stats stats = GetStats(channel);
  EXPECT_EQ(stats.jobs_accepted(), 0u);
  EXPECT_EQ(stats.calls_refused(), 1u);
}

TEST(OperationsTest, APortInUseIsRefused) {
  std::unique_ptr<server::Server> first = StartServer({});
  ASSERT_TRUE(first);
  server::ServerOptions second;
  second.listen_address = absl::StrCat("127.0.0.1:", first->port());
  second.log = false;
  absl::StatusOr<std::unique_ptr<server::Server>> started = server::Server::Start(second);
  EXPECT_EQ(started.status().code(), absl::StatusCode::kUnavailable);
}

TEST(WorkersTest, CpuWorkersGiveTheSameResultsAsOneWorker) {
  server::ServerOptions single;
  single.gpu = server::GpuMode::kOff;
  server::ServerOptions pool = single;
  pool.cpu_workers = 3;
  std::unique_ptr<server::Server> one = StartServer(single);
  std::unique_ptr<server::Server> three = StartServer(pool);
  ASSERT_TRUE(one && three);
  auto one_channel = client::Connect(absl::StrCat("127.0.0.1:", one->port()));
  auto pool_channel = client::Connect(absl::StrCat("127.0.0.1:", three->port()));
  EXPECT_EQ(GetStats(pool_channel).cpu_workers(), 3u);
  std::vector<std::string> inputs;
  for (int n : {20, 30, 25, 35, 15, 40}) inputs.push_back(*EncodeMeshToDraco(testing::Grid(n)));
  std::vector<v1::JobSpec> specs = {MeshSpec(v1::ALGORITHM_HC), MeshSpec(v1::ALGORITHM_ML),
                                    MeshSpec(v1::ALGORITHM_EMLO, 12)};
  std::vector<std::future<absl::StatusOr<client::JobResult>>> concurrent;
  for (size_t i = 0; i < inputs.size(); ++i) {
    concurrent.push_back(std::async(std::launch::async, [&, i] {
      return client::RunJob(pool_channel, specs[i % specs.size()], inputs[i]);
    }));
  }
  for (size_t i = 0; i < inputs.size(); ++i) {
    absl::StatusOr<client::JobResult> got = concurrent[i].get();
    absl::StatusOr<client::JobResult> expected =
        client::RunJob(one_channel, specs[i % specs.size()], inputs[i]);
    ASSERT_TRUE(got.ok() && expected.ok()) << got.status() << expected.status();
    ExpectSameHierarchy(expected->hierarchy, got->hierarchy);
  }
}

// A waiting job hears its place in the queue when it changes (Progress.queue_position).
TEST(WorkersTest, WaitingJobsReceiveTheirQueuePosition) {
  server::ServerOptions options;
  options.gpu = server::GpuMode::kOff;
  std::unique_ptr<server::Server> server = StartServer(options);
  ASSERT_TRUE(server);
  auto channel = client::Connect(absl::StrCat("127.0.0.1:", server->port()));
  const std::string big = *EncodeMeshToDraco(testing::Grid(300));
  const std::string small = *EncodeMeshToDraco(testing::Grid(10));
  auto running = std::async(
      std::launch::async, [&] { return client::RunJob(channel, MeshSpec(v1::ALGORITHM_HC), big); });
  for (int i = 0; i < 500 && GetStats(channel).jobs_running() == 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  std::promise<void> first_queued;
  auto first = std::async(std::launch::async, [&] {
    client::RunOptions run_options;
    bool told = false;
    run_options.on_event = [&](const v1::JobEvent& event) {
      if (event.has_accepted() && !told) {
        told = true;
        first_queued.set_value();
      }
    };
    return client::RunJob(channel, MeshSpec(v1::ALGORITHM_HC), small, run_options);
  });
  first_queued.get_future().wait();
  std::vector<uint32_t> positions;
  client::RunOptions run_options;
  run_options.on_event = [&](const v1::JobEvent& event) {
    if (event.has_accepted()) positions.push_back(event.accepted().queue_position());
    if (event.has_progress() && event.progress().stage() == "queued") {
      positions.push_back(event.progress().queue_position());
    }
  };
  absl::StatusOr<client::JobResult> second =
      client::RunJob(channel, MeshSpec(v1::ALGORITHM_HC), small, run_options);
  ASSERT_TRUE(second.ok()) << second.status();
  ASSERT_TRUE(first.get().ok());
  ASSERT_TRUE(running.get().ok());
  // Accepted with one job ahead (the first small one; the running job is not waiting),
  // then told it is next when the first one starts.
  EXPECT_EQ(positions, (std::vector<uint32_t>{1, 0}));
}

// SIGTERM's path: the running job finishes within the drain time; queued jobs end at once
// with UNAVAILABLE and a message; health turns NOT_SERVING; no client hangs.
TEST(OperationsTest, ShutdownDrainsRunningJobsAndFailsQueuedOnes) {
  server::ServerOptions options;
  options.drain_time = absl::Seconds(120);
  options.gpu = server::GpuMode::kOff;
  std::unique_ptr<server::Server> server = StartServer(options);
  ASSERT_TRUE(server);
  auto channel = client::Connect(absl::StrCat("127.0.0.1:", server->port()));
  const std::string big = *EncodeMeshToDraco(testing::Grid(300));  // 180k faces
  const std::string small = *EncodeMeshToDraco(testing::Grid(10));
  auto running = std::async(
      std::launch::async, [&] { return client::RunJob(channel, MeshSpec(v1::ALGORITHM_HC), big); });
  for (int i = 0; i < 500 && GetStats(channel).jobs_running() == 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_EQ(GetStats(channel).jobs_running(), 1u);
  std::vector<std::future<absl::StatusOr<client::JobResult>>> queued;
  for (int i = 0; i < 2; ++i) {
    queued.push_back(std::async(std::launch::async, [&] {
      return client::RunJob(channel, MeshSpec(v1::ALGORITHM_HC), small);
    }));
  }
  for (int i = 0; i < 500 && GetStats(channel).queue_depth() < 2; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_EQ(GetStats(channel).queue_depth(), 2u);
  std::thread shutdown([&] { server->Shutdown(); });
  for (auto& job : queued) {
    absl::StatusOr<client::JobResult> result = job.get();
    EXPECT_EQ(result.status().code(), absl::StatusCode::kUnavailable) << result.status();
    EXPECT_THAT(result.status().message(), HasSubstr("shutting down"));
  }
  absl::StatusOr<client::JobResult> finished = running.get();
  ASSERT_TRUE(finished.ok()) << finished.status();
  EXPECT_EQ(finished->done.final_clusters(), 1u);
  shutdown.join();
}

// Issue 24, item 6: a client that read slowly lost its final event at SIGTERM (its call
// was cancelled with events still unread). Now the unread events are dropped at shutdown
// and the call ends with a final Failed event saying why.
TEST(OperationsTest, ASlowReaderAtShutdownStillGetsAFinalEvent) {
  server::ServerOptions options;
  options.max_event_bytes = 64 << 10;  // many events
  std::unique_ptr<server::Server> server = StartServer(options);
  ASSERT_TRUE(server);
  auto channel = client::Connect(testing::AddressOf(*server));
  auto narrow = testing::NarrowChannelTo(*server);
  const std::string mesh = *EncodeMeshToDraco(testing::Grid(250));  // 125,000 faces
  auto stub = v1::Clustering::NewStub(narrow);
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(300));
  auto stream = stub->Run(&context);
  v1::RunRequest request;
  *request.mutable_spec() = MeshSpec(v1::ALGORITHM_HC);
  request.mutable_spec()->set_input_bytes(mesh.size());
  request.set_chunk(mesh);
  ASSERT_TRUE(stream->Write(request));
  stream->WritesDone();
  v1::JobEvent event;
  ASSERT_TRUE(stream->Read(&event));
  ASSERT_TRUE(event.has_accepted());
  // The client reads nothing more until its job has ended (its levels wait unread) ...
  for (int i = 0; i < 6000 && GetStats(channel).jobs_succeeded() == 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_EQ(GetStats(channel).jobs_succeeded(), 1u);
  // ... then the server is told to stop, and the client reads slowly.
  std::thread shutdown([&] { server->Shutdown(); });
  v1::JobEvent last;
  for (int i = 0; i < 100000 && stream->Read(&event); ++i) {
    last = event;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  const grpc::Status status = stream->Finish();
  shutdown.join();
  EXPECT_TRUE(last.final());
  EXPECT_EQ(last.failed().code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_THAT(status.error_message(), HasSubstr("had not read all of the job's events"));
}

TEST(OperationsTest, ShutdownCancelsRunningJobsWhenTheDrainTimeRunsOut) {
  server::ServerOptions options;  // drain time 0
  options.gpu = server::GpuMode::kOff;
  std::unique_ptr<server::Server> server = StartServer(options);
  ASSERT_TRUE(server);
  auto channel = client::Connect(absl::StrCat("127.0.0.1:", server->port()));
  const std::string big = *EncodeMeshToDraco(testing::Grid(400));
  auto running = std::async(
      std::launch::async, [&] { return client::RunJob(channel, MeshSpec(v1::ALGORITHM_HC), big); });
  for (int i = 0; i < 500 && GetStats(channel).jobs_running() == 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  server->Shutdown();
  absl::StatusOr<client::JobResult> result = running.get();
  // Cancelled with a message, or finished if it was faster than the shutdown.
  if (!result.ok()) {
    EXPECT_EQ(result.status().code(), absl::StatusCode::kUnavailable) << result.status();
    EXPECT_THAT(result.status().message(), HasSubstr("drain time"));
  }
}

}  // namespace
}  // namespace mlclust

namespace mlclust {
namespace {

// Issue 24, item 4: a label with a newline and ANSI escapes cannot forge a log line, and an
// 8 MiB label is not logged whole, in text and in JSON (each line parses). (A label is a
// proto3 string: bytes that are not UTF-8 never reach the server; LogSafeTest has them.)
TEST(LogInjectionTest, ALabelCannotForgeALineAndABigOneIsCutInBothFormats) {
  const std::string forging =
      "x\n2026-01-01T00:00:00.000Z mlclust: job-1 done in 1s\x1b[2K\x1b]0;owned\x07\xc2\x9b";
  const std::string big(8 << 20, 'b');
  const std::string bytes = *EncodeMeshToDraco(testing::Grid(5));
  for (bool json : {false, true}) {
    server::ServerOptions options;
    options.listen_address = "127.0.0.1:0";
    options.gpu = server::GpuMode::kOff;
    options.log_json = json;
    const std::string out = testing::CaptureStderr([&] {
      absl::StatusOr<std::unique_ptr<server::Server>> server = server::Server::Start(options);
      ASSERT_TRUE(server.ok()) << server.status();
      auto channel = testing::ChannelTo(**server);
      for (const std::string& label : {forging, big}) {
        EXPECT_TRUE(client::RunJob(channel, MeshSpec(v1::ALGORITHM_HC, 0, label), bytes).ok());
      }
      (*server)->Shutdown();
    });
    server::JsonLogs() = false;
    const std::vector<std::string> lines = testing::LinesOf(out);
    ASSERT_GE(lines.size(), 4u) << out.substr(0, 2000);
    int escaped = 0, cut = 0;
    for (const std::string& line : lines) {
      EXPECT_THAT(line, Not(HasSubstr("\x1b"))) << line;
      EXPECT_THAT(line, Not(HasSubstr("\x07"))) << line;
      EXPECT_LT(line.size(), size_t{8192}) << line.substr(0, 200);
      if (json) {
        google::protobuf::Struct parsed;
        EXPECT_TRUE(google::protobuf::util::JsonStringToMessage(line, &parsed).ok()) << line;
      } else {
        EXPECT_THAT(line, ::testing::MatchesRegex("[0-9]{4}-[0-9T:.-]+Z mlclust: .*")) << line;
        EXPECT_FALSE(absl::StartsWith(line, "2026-01-01T00:00:00.000Z")) << "forged: " << line;
      }
      if (line.find("x\\\\x0a2026") != std::string::npos ||
          line.find("x\\x0a2026") != std::string::npos) {
        ++escaped;
      }
      if (line.find("...[8388608 bytes]") != std::string::npos) ++cut;
    }
    EXPECT_GE(escaped, 1) << (json ? "json" : "text");
    EXPECT_GE(cut, 1) << (json ? "json" : "text");
  }
}

}  // namespace
}  // namespace mlclust

namespace mlclust {
namespace {

// Issue 24, item 7: streams of the wrong shape were answered but not logged. Each is a
// call_failed line now (not counted as a refusal).
TEST(LogInjectionTest, MalformedStreamsAreLogged) {
  server::ServerOptions options;
  options.listen_address = "127.0.0.1:0";
  options.gpu = server::GpuMode::kOff;
  const std::string out = testing::CaptureStderr([&] {
    absl::StatusOr<std::unique_ptr<server::Server>> server = server::Server::Start(options);
    ASSERT_TRUE(server.ok()) << server.status();
    auto stub = v1::Clustering::NewStub(testing::ChannelTo(**server));
    for (int shape = 0; shape < 3; ++shape) {
      grpc::ClientContext context;
      context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(60));
      auto stream = stub->Run(&context);
      v1::RunRequest request;
      if (shape != 1) {
        *request.mutable_spec() = MeshSpec(v1::ALGORITHM_HC);
        request.mutable_spec()->set_input_bytes(10);
      }
      request.set_chunk(shape == 2 ? std::string(11, 'x') : std::string("x"));
      stream->Write(request);
      if (shape == 0) stream->Write(request);  // a second spec
      stream->WritesDone();
      v1::JobEvent event;
      while (stream->Read(&event)) {
      }
      EXPECT_EQ(stream->Finish().error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    }
    (*server)->Shutdown();
  });
  EXPECT_THAT(out, HasSubstr("a second job spec in the same call"));
  EXPECT_THAT(out, HasSubstr("the first message of a call must carry the job spec"));
  EXPECT_THAT(out, HasSubstr("more input than spec.input_bytes = 10"));
  EXPECT_THAT(out, HasSubstr("a call failed from ipv4:127.0.0.1:"));
}

}  // namespace
}  // namespace mlclust
