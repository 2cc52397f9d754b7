#include "server/metrics.h"

#include <thread>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "httplib.h"

namespace mlclust::server {

void JobMetrics::Histogram::Add(double value) {
  for (size_t i = 0; i < kBuckets.size(); ++i) {
    if (value <= kBuckets[i]) ++buckets[i];
  }
  ++count;
  sum += value;
}

void JobMetrics::JobEnded(const std::string& algorithm, const std::string& outcome,
                          double seconds_queued, double seconds_running) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++ended_[{algorithm, outcome}];
  queued_[algorithm].Add(seconds_queued);
  running_[algorithm].Add(seconds_running);
}

std::string PrometheusLabel(const std::string& value) {
  std::string out;
  for (char c : value) {
    if (c == '\\' || c == '"') out += '\\';
    if (c == '\n') {
      out += "\\n";
      continue;
    }
    out += c;
  }
  return out;
}

std::string JobMetrics::Render() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::string out =
      "# HELP mlclust_jobs_ended_total Jobs that ended, by algorithm and outcome.\n"
      "# TYPE mlclust_jobs_ended_total counter\n";
  for (const auto& [key, count] : ended_) {
    absl::StrAppend(&out, "mlclust_jobs_ended_total{algorithm=\"", PrometheusLabel(key.first),
                    "\",outcome=\"", key.second, "\"} ", count, "\n");
  }
  auto histograms = [&](const char* name, const char* help,
                        const std::map<std::string, Histogram>& by_algorithm) {
    absl::StrAppend(&out, "# HELP ", name, " ", help, "\n# TYPE ", name, " histogram\n");
    for (const auto& [algorithm, histogram] : by_algorithm) {
      const std::string label = PrometheusLabel(algorithm);
      for (size_t i = 0; i < kBuckets.size(); ++i) {
        absl::StrAppend(&out, name, "_bucket{algorithm=\"", label, "\",le=\"", kBuckets[i], "\"} ",
                        histogram.buckets[i], "\n");
      }
      absl::StrAppend(&out, name, "_bucket{algorithm=\"", label, R"(",le="+Inf"} )",
                      histogram.count, "\n", name, "_sum{algorithm=\"", label, "\"} ",
                      absl::StrFormat("%.6f", histogram.sum), "\n", name, "_count{algorithm=\"",
                      label, "\"} ", histogram.count, "\n");
    }
  };
  histograms("mlclust_job_queued_seconds", "Time jobs waited in the queue, by algorithm.", queued_);
  histograms("mlclust_job_running_seconds", "Time jobs ran (decode to done), by algorithm.",
             running_);
  return out;
}

// Workers answering /metrics: idle connections are dropped after 1 s, so this many idle
// or slow clients at once are needed to delay a scrape.
constexpr size_t kMetricsThreads = 32;

struct MetricsHttpServer::Impl {
  httplib::Server http;
  std::thread thread;
};

absl::StatusOr<std::unique_ptr<MetricsHttpServer>> MetricsHttpServer::Start(
    const std::string& address, std::function<std::string()> render,
    std::function<std::string()> not_ready) {
  const size_t colon = address.rfind(':');
  int port = -1;
  if (colon == std::string::npos || !absl::SimpleAtoi(address.substr(colon + 1), &port) ||
      port < 0 || port > 65535) {
    return absl::InvalidArgumentError(
        absl::StrCat("--metrics: '", address, "' is not HOST:PORT (e.g. 127.0.0.1:9090)"));
  }
  std::string host = address.substr(0, colon);
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']') {
    host = host.substr(1, host.size() - 2);
  }
  std::unique_ptr<MetricsHttpServer> server(new MetricsHttpServer());
  server->impl_ = std::make_unique<Impl>();
  httplib::Server& http = server->impl_->http;
  // Idle or slow connections must not hold every worker (issue 24: 8 idle sockets blocked
  // /metrics): more workers than a scraper needs, and a connection that sends nothing for
  // a second is dropped.
  http.new_task_queue = [] { return new httplib::ThreadPool(kMetricsThreads); };
  http.set_read_timeout(1, 0);
  http.set_write_timeout(5, 0);
  http.set_keep_alive_timeout(1);
  http.set_keep_alive_max_count(16);
  http.Get("/metrics", [render](const httplib::Request&, httplib::Response& response) {
    response.set_content(render(), "text/plain; version=0.0.4; charset=utf-8");
  });
  if (not_ready) {
    http.Get("/ready", [not_ready](const httplib::Request&, httplib::Response& response) {
      const std::string reason = not_ready();
      response.status = reason.empty() ? 200 : 503;
      response.set_content(reason.empty() ? std::string("ready\n") : reason + "\n",
                           "text/plain; charset=utf-8");
    });
  }
  // No SO_REUSEADDR surprises: a port in use is refused like the gRPC one.
  http.set_socket_options([](socket_t socket) {
    int no = 0;
    setsockopt(socket, SOL_SOCKET, SO_REUSEPORT, &no, sizeof(no));
  });
  if (port == 0) {
    server->port_ = http.bind_to_any_port(host);
  } else {
    server->port_ = http.bind_to_port(host, port) ? port : -1;
  }
  if (server->port_ <= 0) {
    return absl::UnavailableError(absl::StrCat("--metrics: cannot listen on '", address,
                                               "' (in use, or not an address of "
                                               "this host)"));
  }
  server->impl_->thread = std::thread([&http] { http.listen_after_bind(); });
  // stop() before the loop runs would be lost (and the join would wait for ever).
  for (int i = 0; i < 5000 && !http.is_running(); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return server;
}

MetricsHttpServer::~MetricsHttpServer() {
  if (impl_ == nullptr) return;
  impl_->http.stop();
  if (impl_->thread.joinable()) impl_->thread.join();
}

}  // namespace mlclust::server
