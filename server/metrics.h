// Prometheus metrics: the job counters and duration histograms the server keeps, their
// text exposition (format 0.0.4), and the small HTTP server that serves GET /metrics
// (Debian's cpp-httplib) on its own thread, apart from the gRPC port.
#ifndef MLCLUST_SERVER_METRICS_H_
#define MLCLUST_SERVER_METRICS_H_

#include <array>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <utility>

#include "absl/status/statusor.h"

namespace mlclust::server {

// Jobs ended, by algorithm and outcome, and histograms of their time queued and running,
// by algorithm. Thread-safe.
class JobMetrics {
 public:
  // `outcome`: "succeeded", "failed", "cancelled".
  void JobEnded(const std::string& algorithm, const std::string& outcome, double seconds_queued,
                double seconds_running);
  // mlclust_jobs_ended_total, mlclust_job_queued_seconds, mlclust_job_running_seconds.
  std::string Render() const;

  // Bucket bounds in seconds (and +Inf).
  static constexpr std::array<double, 13> kBuckets = {0.01, 0.05, 0.1, 0.25, 0.5, 1,  2.5,
                                                      5,    10,   30,  60,   120, 300};

 private:
  struct Histogram {
    std::array<uint64_t, kBuckets.size()> buckets{};  // cumulative counts per bound
    uint64_t count = 0;
    double sum = 0;
    void Add(double value);
  };
  mutable std::mutex mutex_;
  std::map<std::pair<std::string, std::string>, uint64_t> ended_;
  std::map<std::string, Histogram> queued_, running_;
};

// A label value escaped for the exposition format.
std::string PrometheusLabel(const std::string& value);

// GET /metrics on `address` ("HOST:PORT"; port 0 picks one) answering `render()`, and,
// with `not_ready`, GET /ready: 200 "ready" when not_ready() is empty, else 503 with its
// reason (readiness for probes that speak no gRPC or no TLS: docker/k8s/tls); any other
// path is 404. Stops on destruction.
class MetricsHttpServer {
 public:
  static absl::StatusOr<std::unique_ptr<MetricsHttpServer>> Start(
      const std::string& address, std::function<std::string()> render,
      std::function<std::string()> not_ready = nullptr);
  ~MetricsHttpServer();
  int port() const { return port_; }

 private:
  MetricsHttpServer() = default;
  struct Impl;
  std::unique_ptr<Impl> impl_;
  int port_ = 0;
};

}  // namespace mlclust::server

#endif  // MLCLUST_SERVER_METRICS_H_
