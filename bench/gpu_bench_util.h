// What the GPU-against-CPU bench mains (pml_gpu_bench, hc_gpu_bench, points_gpu_bench)
// share: the process's CPU time, a per-level fingerprint of the triplets, the GL context
// they run on, and the best-of-R runs on the CPU and the GPU.
#ifndef MLCLUST_BENCH_GPU_BENCH_UTIL_H_
#define MLCLUST_BENCH_GPU_BENCH_UTIL_H_

#include <sys/resource.h>

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "bench/bench_util.h"
#include "core/hierarchy/hierarchy.h"
#include "gpu/context/gl_context.h"

namespace mlclust::bench {

// The process's CPU seconds so far (user + system, all threads: llvmpipe's included).
inline double ProcessCpuSeconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
}

// An order-independent fingerprint of a level's triplets and its cluster count.
inline uint64_t LevelFingerprint(const LevelMoves& level) {
  uint64_t print = level.cluster_count;
  for (size_t i = 0; i < level.element.size(); ++i) {
    uint64_t x = (uint64_t{level.element[i]} << 32) ^
                 (uint64_t{level.to_cluster[i]} * 0x9E3779B97F4A7C15ull) ^ level.from_cluster[i];
    x ^= x >> 31;
    x *= 0xBF58476D1CE4E5B9ull;
    x ^= x >> 29;
    print += x;
  }
  return print;
}

// A GL context, or null after printing why there is none to stderr.
inline std::unique_ptr<gpu::GlContext> GlContextOrPrint() {
  absl::StatusOr<std::unique_ptr<gpu::GlContext>> context = gpu::GlContext::Create();
  if (!context.ok()) {
    std::fprintf(stderr, "%s\n", context.status().ToString().c_str());
    return nullptr;
  }
  return *std::move(context);
}

// Per level an order-independent fingerprint (LevelFingerprint; the start: its cluster
// count) and the energy.
class LevelPrintSink : public LevelSink {
 public:
  absl::Status OnStart(std::span<const ClusterId> /*labels*/, uint32_t count,
                       double energy) override {
    prints.push_back(count);
    energies.push_back(energy);
    return absl::OkStatus();
  }
  absl::Status OnLevel(const LevelMoves& level) override {
    prints.push_back(LevelFingerprint(level));
    energies.push_back(level.energy);
    return absl::OkStatus();
  }
  std::vector<uint64_t> prints;
  std::vector<double> energies;
};

// How many of the first levels of `a` and `b` are the same (a[l] == b[l]).
template <typename T>
size_t SameLevels(const std::vector<T>& a, const std::vector<T>& b) {
  size_t same = 0;
  for (size_t l = 0; l < a.size() && l < b.size(); ++l) same += a[l] == b[l] ? 1 : 0;
  return same;
}

// One device's row: the best wall time of R runs and the process CPU time of that run,
// the last run's summary and sink.
template <typename Summary, typename Sink>
struct DeviceRun {
  std::string device;
  double seconds = std::numeric_limits<double>::infinity();
  double cpu_seconds = 0;
  Summary summary;
  std::optional<Sink> sink;
};

// The CPU's runs (row 0, "cpu") and the GPU's (row 1, the context's renderer), `repeats`
// each (at least one): run(device, sink) with device 0 or 1 and a fresh make_sink() per run returns
// an absl::StatusOr<Summary>. Null after printing the first error to stderr.
template <typename Summary, typename Sink, typename MakeSink, typename Run>
std::optional<std::array<DeviceRun<Summary, Sink>, 2>> RunOnCpuAndGpu(const gpu::GlContext& context,
                                                                      uint32_t repeats,
                                                                      MakeSink make_sink, Run run) {
  std::array<DeviceRun<Summary, Sink>, 2> rows;
  rows[0].device = "cpu";
  rows[1].device = context.renderer();
  for (int device = 0; device < 2; ++device) {
    for (uint32_t r = 0; r < std::max(repeats, 1u); ++r) {
      Sink sink = make_sink();
      const double cpu_before = ProcessCpuSeconds();
      const Stopwatch watch;
      absl::StatusOr<Summary> summary = run(device, sink);
      const double seconds = watch.Seconds();
      const double cpu_seconds = ProcessCpuSeconds() - cpu_before;
      if (!summary.ok()) {
        std::fprintf(stderr, "%s\n", summary.status().ToString().c_str());
        return std::nullopt;
      }
      DeviceRun<Summary, Sink>& row = rows[device];
      if (seconds < row.seconds) {
        row.seconds = seconds;
        row.cpu_seconds = cpu_seconds;
      }
      row.summary = *std::move(summary);
      row.sink.emplace(std::move(sink));
    }
  }
  return rows;
}

}  // namespace mlclust::bench

#endif  // MLCLUST_BENCH_GPU_BENCH_UTIL_H_
