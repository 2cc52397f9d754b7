// The Prometheus endpoint and the JSON log lines of a real server on loopback: counts by
// algorithm and outcome, histograms, bytes in and out, 404 elsewhere, a port in use
// refused; one JSON object per log line with the job's fields.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <future>
#include <thread>

#include "absl/strings/match.h"
#include "absl/strings/str_split.h"
#include "client/client.h"
#include "core/io/draco_codec.h"
#include "mlclust/v1/mlclust.grpc.pb.h"
#include "server/log.h"
#include "server/server.h"
#include "tests/fixtures/loopback.h"
#include "tests/fixtures/test_meshes.h"

namespace mlclust {
namespace {

using ::testing::HasSubstr;

// GET `path` from 127.0.0.1:`port` over plain HTTP/1.0; the whole response.
using testing::HttpGet;

// The value of the sample line that starts with `name` (labels included), or -1.
double Sample(const std::string& metrics, const std::string& name) {
  for (absl::string_view line : absl::StrSplit(metrics, '\n')) {
    if (line.size() > name.size() && line.substr(0, name.size()) == name &&
        line[name.size()] == ' ') {
      return std::stod(std::string(line.substr(name.size() + 1)));
    }
  }
  return -1;
}

v1::JobSpec MeshSpec(v1::Algorithm algorithm) {
  v1::JobSpec spec;
  spec.set_input_kind(v1::INPUT_KIND_DRACO_MESH);
  spec.set_algorithm(algorithm);
  spec.set_label("metrics \"test\"");
  return spec;
}

// A server on free loopback ports for gRPC and the metrics, with `gpu`.
server::ServerOptions WithMetrics(server::GpuMode gpu) {
  server::ServerOptions options;
  options.listen_address = "127.0.0.1:0";
  options.metrics_address = "127.0.0.1:0";
  options.gpu = gpu;
  return options;
}

TEST(MetricsTest, CountsJobsByAlgorithmAndOutcomeWithDurationsAndBytes) {
  server::ServerOptions options = WithMetrics(server::GpuMode::kOff);
  options.log_json = true;
  ::testing::internal::CaptureStderr();
  absl::StatusOr<std::unique_ptr<server::Server>> started = server::Server::Start(options);
  ASSERT_TRUE(started.ok()) << started.status();
  server::Server& server = **started;
  ASSERT_GT(server.metrics_port(), 0);
  auto channel = client::Connect(absl::StrCat("127.0.0.1:", server.port()));

  const std::string mesh = *EncodeMeshToDraco(testing::Grid(10));
  ASSERT_TRUE(client::RunJob(channel, MeshSpec(v1::ALGORITHM_HC), mesh).ok());
  ASSERT_TRUE(client::RunJob(channel, MeshSpec(v1::ALGORITHM_HC), mesh).ok());
  // A job that is accepted and then fails: a Draco header the server checks before
  // Accepted, a body cut short that only the decoder finds (bytes that are not Draco at all
  // are refused before Accepted, and never counted as a job).
  const std::string garbage = mesh.substr(0, mesh.size() / 2);
  EXPECT_EQ(client::RunJob(channel, MeshSpec(v1::ALGORITHM_ML), garbage).status().code(),
            absl::StatusCode::kInvalidArgument);
  absl::StatusOr<v1::Accepted> detached =
      client::SubmitDetached(channel, MeshSpec(v1::ALGORITHM_HC), mesh);
  ASSERT_TRUE(detached.ok());
  ASSERT_TRUE(client::WatchJob(channel, detached->job_id()).ok());

  // A job's stream can end before the worker has recorded its outcome: read until the four
  // outcomes are there (at most 10 s), then check every figure.
  std::string response;
  for (int attempt = 0; attempt < 200; ++attempt) {
    response = HttpGet(server.metrics_port(), "/metrics");
    if (Sample(response, R"(mlclust_jobs_ended_total{algorithm="hc",outcome="succeeded"})") == 3 &&
        Sample(response, R"(mlclust_jobs_ended_total{algorithm="ml",outcome="failed"})") == 1) {
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  EXPECT_THAT(response, HasSubstr("200 OK"));
  // Issue 24, item 7: no gauge with the reserved _count suffix; the build as a metric.
  EXPECT_EQ(Sample(response, "mlclust_jobs_running"), 0);
  EXPECT_THAT(response, ::testing::Not(HasSubstr("mlclust_jobs_running_count")));
  EXPECT_THAT(response, ::testing::ContainsRegex(R"(mlclust_build_info\{version="[0-9.]+",)"));
  EXPECT_THAT(response, HasSubstr("text/plain; version=0.0.4"));
  EXPECT_EQ(Sample(response, R"(mlclust_jobs_ended_total{algorithm="hc",outcome="succeeded"})"), 3);
  EXPECT_EQ(Sample(response, R"(mlclust_jobs_ended_total{algorithm="ml",outcome="failed"})"), 1);
  EXPECT_EQ(Sample(response, R"(mlclust_job_running_seconds_count{algorithm="hc"})"), 3);
  EXPECT_EQ(Sample(response, R"(mlclust_job_running_seconds_bucket{algorithm="hc",le="+Inf"})"), 3);
  EXPECT_GE(Sample(response, R"(mlclust_job_running_seconds_bucket{algorithm="hc",le="300"})"),
            Sample(response, R"(mlclust_job_running_seconds_bucket{algorithm="hc",le="0.01"})"));
  EXPECT_EQ(Sample(response, "mlclust_input_bytes_total"), 3 * mesh.size() + garbage.size());
  EXPECT_GT(Sample(response, "mlclust_output_bytes_total"), 3 * 200 * 4);
  EXPECT_EQ(Sample(response, "mlclust_queue_depth"), 0);
  EXPECT_EQ(Sample(response, "mlclust_jobs_accepted_total"), 4);
  EXPECT_EQ(Sample(response, "mlclust_gpu_available"), 0);
  EXPECT_GT(Sample(response, "mlclust_kept_result_bytes"), 0);
  EXPECT_THAT(HttpGet(server.metrics_port(), "/other"), HasSubstr("404"));

  // A metrics port in use is refused.
  server::ServerOptions second = options;
  second.metrics_address = absl::StrCat("127.0.0.1:", server.metrics_port());
  second.log = false;
  absl::StatusOr<std::unique_ptr<server::Server>> refused = server::Server::Start(second);
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kUnavailable);
  EXPECT_THAT(refused.status().message(), HasSubstr("--metrics"));

  started->reset();
  const std::string logs = ::testing::internal::GetCapturedStderr();
  int accepted = 0, ended = 0;
  for (absl::string_view line : absl::StrSplit(logs, '\n', absl::SkipEmpty())) {
    ASSERT_EQ(line.front(), '{') << line;
    ASSERT_EQ(line.back(), '}') << line;
    EXPECT_THAT(std::string(line), HasSubstr(R"("time":")"));
    EXPECT_THAT(std::string(line),
                ::testing::ContainsRegex(R"re("level":"(info|warning|error)")re"));
    if (absl::StrContains(line, R"("event":"job_accepted")")) {
      ++accepted;
      EXPECT_THAT(std::string(line), HasSubstr(R"("label":"metrics \"test\"")"));
      EXPECT_THAT(std::string(line), HasSubstr(R"("tenant":"")"));
    }
    if (absl::StrContains(line, R"("event":"job_ended")")) {
      ++ended;
      EXPECT_THAT(std::string(line), HasSubstr(R"("seconds_running":)"));
      EXPECT_THAT(std::string(line), HasSubstr(R"("input_bytes":)"));
      if (absl::StrContains(line, R"("outcome":"failed")")) {
        EXPECT_THAT(std::string(line), HasSubstr(R"("algorithm":"ml")"));
        EXPECT_THAT(std::string(line), HasSubstr(R"("code":"INVALID_ARGUMENT")"));
        EXPECT_THAT(std::string(line), HasSubstr(R"("level":"error")"));
      }
    }
  }
  EXPECT_EQ(accepted, 4);
  EXPECT_EQ(ended, 4);
  // Issue 24, item 7: a line when the server is told to stop (SIGTERM), with a level.
  EXPECT_THAT(logs, HasSubstr(R"("level":"warning","event":"shutdown")"));
  server::JsonLogs() = false;
}

// GPU memory: the buffers of the server's GL context (llvmpipe where there is no GPU) while
// and after a job with a GPU stage, in the metrics and in Stats; the device's total and free
// memory only where the driver exposes them (not on llvmpipe: those lines are absent).
TEST(MetricsTest, GpuMemoryOfTheGlContextAndTheDeviceWhereExposed) {
  server::ServerOptions options = WithMetrics(server::GpuMode::kAuto);
  options.log = false;
  absl::StatusOr<std::unique_ptr<server::Server>> started = server::Server::Start(options);
  ASSERT_TRUE(started.ok()) << started.status();
  server::Server& server = **started;
  auto channel = client::Connect(absl::StrCat("127.0.0.1:", server.port()));
  const bool gpu = !server.gl_renderer().empty();
  v1::JobSpec spec = MeshSpec(v1::ALGORITHM_BB);
  spec.set_energy(v1::ENERGY_CVD);
  spec.set_clusters(20);
  spec.set_device(gpu ? "gpu" : "cpu");  // BB's decide stage on the GL context
  ASSERT_TRUE(client::RunJob(channel, spec, *EncodeMeshToDraco(testing::Grid(30))).ok());

  const std::string response = HttpGet(server.metrics_port(), "/metrics");
  auto stub = v1::Clustering::NewStub(channel);
  grpc::ClientContext context;
  v1::Stats stats;
  ASSERT_TRUE(stub->GetStats(&context, v1::GetStatsRequest(), &stats).ok());
  // Every buffer of the ended job is freed; the peak says how much it took.
  EXPECT_EQ(Sample(response, "mlclust_gpu_memory_bytes"), 0);
  EXPECT_EQ(stats.gpu_buffer_bytes(), 0u);
  EXPECT_EQ(Sample(response, "mlclust_gpu_memory_peak_bytes"),
            static_cast<double>(stats.gpu_buffer_peak_bytes()));
  if (gpu) {
    // 1,800 faces: at least a label (4 bytes) per face went to the GL context.
    EXPECT_GE(stats.gpu_buffer_peak_bytes(), 4u * 1800);
  } else {
    EXPECT_EQ(stats.gpu_buffer_peak_bytes(), 0u);
  }
  const bool exposed = stats.has_gpu_device_memory_available_bytes();
  EXPECT_EQ(Sample(response, "mlclust_gpu_device_memory_available_bytes") >= 0, exposed);
  EXPECT_EQ(Sample(response, "mlclust_gpu_device_memory_total_bytes") >= 0,
            stats.has_gpu_device_memory_total_bytes());
  if (!gpu || absl::StrContains(server.gl_renderer(), "llvmpipe")) {
    EXPECT_FALSE(exposed);  // "not exposed": the lines are left out
    EXPECT_FALSE(stats.has_gpu_device_memory_total_bytes());
    EXPECT_THAT(response, ::testing::Not(HasSubstr("mlclust_gpu_device_memory")));
  } else if (stats.has_gpu_device_memory_total_bytes()) {
    EXPECT_GE(stats.gpu_device_memory_total_bytes(), stats.gpu_device_memory_available_bytes());
  }
}

}  // namespace
}  // namespace mlclust

namespace mlclust {
namespace {

// Issue 24, item 5: 8 idle sockets blocked /metrics (each held one of 8 workers). Here 16
// slow connections that send a byte of a request every 200 ms (so no read ever times out)
// hold workers as long as they go on; a scrape meanwhile still answers.
TEST(MetricsTest, AScrapeAnswersWhileSlowConnectionsHoldWorkers) {
  server::ServerOptions options = WithMetrics(server::GpuMode::kOff);
  options.log = false;
  absl::StatusOr<std::unique_ptr<server::Server>> started = server::Server::Start(options);
  ASSERT_TRUE(started.ok()) << started.status();
  const int port = (*started)->metrics_port();
  std::vector<int> slow;
  for (int i = 0; i < 16; ++i) slow.push_back(testing::ConnectToLoopback(port));
  std::atomic<bool> stop{false};
  std::thread trickle([&] {
    const std::string request = "GET /metrics HTTP/1.1\r\nHost: localhost\r\nX-Slow: ";
    for (size_t i = 0; i < 150 && !stop; ++i) {  // 30 s at most
      for (int fd : slow) (void)!write(fd, request.data() + std::min(i, request.size() - 1), 1);
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
    }
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // they hold workers now
  std::future<std::string> scrape =
      std::async(std::launch::async, [port] { return HttpGet(port, "/metrics"); });
  // Generous: the trickle lasts 30 s; a scrape that waits for it has failed.
  const bool answered = scrape.wait_for(std::chrono::seconds(25)) == std::future_status::ready;
  stop = true;
  trickle.join();
  for (int fd : slow) close(fd);
  ASSERT_TRUE(answered) << "the scrape waited for the slow connections";
  EXPECT_THAT(scrape.get(), HasSubstr("200 OK"));
}

TEST(MetricsTest, WithTokensMetricsStayOnLoopbackUnlessAllowed) {
  server::ServerOptions options;
  options.listen_address = "127.0.0.1:0";
  options.log = false;
  options.gpu = server::GpuMode::kOff;
  options.auth_tokens = {{"alpha-token-0123456789abcdef", "alpha"}};
  options.metrics_address = "0.0.0.0:0";
  // (The TLS check comes after: the metrics address is refused first.)
  absl::StatusOr<std::unique_ptr<server::Server>> remote = server::Server::Start(options);
  EXPECT_EQ(remote.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(remote.status().message(), HasSubstr("loopback only"));
}

}  // namespace
}  // namespace mlclust
