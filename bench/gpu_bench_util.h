// What the GPU-against-CPU bench mains (pml_gpu_bench, hc_gpu_bench, points_gpu_bench)
// share: the process's CPU time, a per-level fingerprint of the triplets, and the GL
// context they run on.
#ifndef MLCLUST_BENCH_GPU_BENCH_UTIL_H_
#define MLCLUST_BENCH_GPU_BENCH_UTIL_H_

#include <sys/resource.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <memory>

#include "absl/status/statusor.h"
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

}  // namespace mlclust::bench

#endif  // MLCLUST_BENCH_GPU_BENCH_UTIL_H_
