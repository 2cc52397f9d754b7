#include "core/cluster/boundary_based.h"

#include "tbb/blocked_range.h"
#include "tbb/parallel_for.h"
#include "tbb/task_arena.h"

namespace mlclust::boundary_based {

struct StageThreads::Arena {
  explicit Arena(int threads)
      : arena(threads > 0 ? threads : static_cast<int>(tbb::task_arena::automatic)) {}
  tbb::task_arena arena;
};

StageThreads::StageThreads(int threads) : arena_(std::make_unique<Arena>(threads)) {}
StageThreads::~StageThreads() = default;

void StageThreads::ParallelFor(size_t n, size_t grain,
                               absl::FunctionRef<void(size_t, size_t)> body) const {
  arena_->arena.execute([&] {
    tbb::parallel_for(
        tbb::blocked_range<size_t>(0, n, grain),
        [&](const tbb::blocked_range<size_t>& range) { body(range.begin(), range.end()); });
  });
}

void ResolveConflicts(const ConnectivityGuard& rings,
                      absl::FunctionRef<bool(uint32_t face, uint32_t to)> allowed,
                      std::span<const uint32_t> target, const StageThreads& threads,
                      ConflictScratch& scratch, std::vector<uint32_t>& accepted) {
  std::vector<uint32_t>& proposed = scratch.proposed;
  proposed.clear();
  for (uint32_t f = 0; f < target.size(); ++f) {
    if (target[f] != kNoMove) proposed.push_back(f);
  }
  // The guard first: only proposals it allows take part in the vertex conflicts.
  std::vector<uint8_t>& live = scratch.allowed;
  live.assign(target.size(), 0);
  threads.ParallelFor(proposed.size(), 256, [&](size_t begin, size_t end) {
    for (size_t i = begin; i != end; ++i) {
      const uint32_t f = proposed[i];
      live[f] = allowed(f, target[f]) ? 1 : 0;
    }
  });
  std::vector<uint8_t>& accept = scratch.accept;
  accept.assign(proposed.size(), 0);
  threads.ParallelFor(proposed.size(), 256, [&](size_t begin, size_t end) {
    for (size_t i = begin; i != end; ++i) {
      const uint32_t f = proposed[i];
      if (!live[f]) continue;
      bool first = true;
      for (uint32_t g : rings.Ring(f)) {
        if (g != ConnectivityGuard::kGap && g < f && live[g]) {
          first = false;
          break;
        }
      }
      accept[i] = first ? 1 : 0;
    }
  });
  accepted.clear();
  for (size_t i = 0; i < proposed.size(); ++i) {
    if (accept[i]) accepted.push_back(proposed[i]);
  }
}

void ResolveConflicts(const ConnectivityGuard& guard, bool check_connectivity,
                      std::span<const uint32_t> labels, std::span<const uint32_t> sizes,
                      std::span<const uint32_t> target, const StageThreads& threads,
                      ConflictScratch& scratch, std::vector<uint32_t>& accepted) {
  ResolveConflicts(
      guard,
      [&](uint32_t face, uint32_t to) {
        return !check_connectivity || guard.CanMove(face, to, labels, sizes);
      },
      target, threads, scratch, accepted);
}

}  // namespace mlclust::boundary_based
