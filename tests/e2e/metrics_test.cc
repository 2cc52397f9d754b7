// The Prometheus endpoint and the JSON log lines of a real server on loopback: counts by
// algorithm and outcome, histograms, bytes in and out, 404 elsewhere, a port in use
// refused; one JSON object per log line with the job's fields.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

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
  const std::string garbage(1000, 'x');
  EXPECT_EQ(client::RunJob(channel, MeshSpec(v1::ALGORITHM_ML), garbage).status().code(),
            absl::StatusCode::kInvalidArgument);
  absl::StatusOr<v1::Accepted> detached =
      client::SubmitDetached(channel, MeshSpec(v1::ALGORITHM_HC), mesh);
  ASSERT_TRUE(detached.ok());
  ASSERT_TRUE(client::WatchJob(channel, detached->job_id()).ok());

  const std::string response = HttpGet(server.metrics_port(), "/metrics");
  EXPECT_THAT(response, HasSubstr("200 OK"));
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
        EXPECT_THAT(std::string(line), HasSubstr(R"("code":3)"));
      }
    }
  }
  EXPECT_EQ(accepted, 4);
  EXPECT_EQ(ended, 4);
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
