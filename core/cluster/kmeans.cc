#include "core/cluster/kmeans.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <span>
#include <utility>

#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"
#include "core/base/random.h"
#include "core/base/status_macros.h"
#include "core/cluster/detail/lloyd.h"
#include "tbb/blocked_range.h"
#include "tbb/parallel_for.h"
#include "tbb/parallel_reduce.h"
#include "tbb/task_arena.h"

namespace mlclust {
namespace {

// Points are processed in blocks of this many; a block is the unit of parallel work and of
// partial sums, which are added in block order, so no result depends on the thread count.
constexpr size_t kBlock = 1024;
// Centres are stored in groups of 8 for the assignment kernel: group g holds, for each
// dimension j, the j-th coordinates of centres 8g..8g+7 side by side, so that one vector
// operation compares a point with 8 centres. Lanes past k hold +inf (never nearest).
constexpr int kLanes = 8;
// Coordinates must span at most this much, so that a squared distance (at most 1024 x the
// square of it) stays finite in float.
constexpr double kMaxExtent = 1e17;
// k-means++ keeps the points transposed in runs of kRun (a block is a whole number of runs),
// and tries at most kMaxCandidates per step (2 + ln k <= 2 + ln 2^32 < 25).
constexpr size_t kRun = 32;
constexpr uint32_t kMaxCandidates = 32;
static_assert(kBlock % kRun == 0);

size_t NumBlocks(size_t m) { return (m + kBlock - 1) / kBlock; }
size_t BlockBegin(size_t block) { return block * kBlock; }
size_t BlockEnd(size_t block, size_t m) { return std::min(m, (block + 1) * kBlock); }

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

// ---------------------------------------------------------------------------------------
// Distance kernels. Written with GCC/Clang vector extensions so that one template serves
// both the baseline x86-64 build (4-wide SSE2) and, where the processor has them, AVX2 with
// FMA (8-wide) through a function compiled for that target and picked once at run time.

#define MLCLUST_INLINE inline __attribute__((always_inline))

template <int W>
struct Vec;
template <>
struct Vec<4> {
  typedef float F __attribute__((vector_size(16)));
  typedef int32_t I __attribute__((vector_size(16)));
  typedef float Unaligned __attribute__((vector_size(16), aligned(4)));
};
template <>
struct Vec<8> {
  typedef float F __attribute__((vector_size(32)));
  typedef int32_t I __attribute__((vector_size(32)));
  typedef float Unaligned __attribute__((vector_size(32), aligned(4)));
};

// Sets every lane of `low` (W lanes of floats or ints) to the least of its lanes, by
// log2(W) rounds of swapping halves (passed by reference: a vector returned by value would
// change the ABI between the baseline and the AVX2 target).
template <int W, typename V>
MLCLUST_INLINE void MinAcrossLanes(V& low) {
  V other;
  if constexpr (W == 8) {
    other = __builtin_shufflevector(low, low, 4, 5, 6, 7, 0, 1, 2, 3);
    low = other < low ? other : low;
    other = __builtin_shufflevector(low, low, 2, 3, 0, 1, 6, 7, 4, 5);
    low = other < low ? other : low;
    other = __builtin_shufflevector(low, low, 1, 0, 3, 2, 5, 4, 7, 6);
    low = other < low ? other : low;
  } else {
    other = __builtin_shufflevector(low, low, 2, 3, 0, 1);
    low = other < low ? other : low;
    other = __builtin_shufflevector(low, low, 1, 0, 3, 2);
    low = other < low ? other : low;
  }
}

// Nearest centre of the P points at `x` (dims D, or `dims` where D == 0) among the centre
// groups; ties go to the smaller centre id. The P points share each load of a centre group
// and give P independent chains of compare-and-select, which hides their latency.
template <int W, int D, int P>
MLCLUST_INLINE void NearestOfGroup(const float* x, uint32_t dims, const float* groups,
                                   uint32_t num_groups, uint32_t* nearest) {
  using F = typename Vec<W>::F;
  using I = typename Vec<W>::I;
  using Unaligned = typename Vec<W>::Unaligned;
  constexpr int kParts = kLanes / W;
  const uint32_t d = D > 0 ? D : dims;
  F best[P][kParts];
  I best_id[P][kParts];
  I id[kParts] = {};
  for (int part = 0; part < kParts; ++part) {
    int32_t first_ids[W];
    for (int lane = 0; lane < W; ++lane) first_ids[lane] = part * W + lane;
    std::memcpy(&id[part], first_ids, sizeof(I));
    for (int p = 0; p < P; ++p) {
      best[p][part] = F{} + std::numeric_limits<float>::infinity();
      best_id[p][part] = I{};
    }
  }
  // Broadcast coordinates, kept in registers where D is known.
  F coordinate[P][D > 0 ? D : 1];
  if constexpr (D > 0) {
    for (int p = 0; p < P; ++p) {
      for (int j = 0; j < D; ++j) coordinate[p][j] = F{} + x[p * D + j];
    }
  }
// Coordinate j of point p, broadcast (a macro: a function returning a vector would be
// compiled for the baseline target and change the ABI).
#define MLCLUST_POINT(p, j) (D > 0 ? coordinate[p][D > 0 ? j : 0] : F{} + x[(p)*d + (j)])
  const float* group = groups;
  for (uint32_t g = 0; g < num_groups; ++g, group += d * kLanes) {
    for (int part = 0; part < kParts; ++part) {
      F sum[P];
      const F c0 = *reinterpret_cast<const Unaligned*>(group + part * W);
      for (int p = 0; p < P; ++p) {
        const F t = c0 - MLCLUST_POINT(p, 0);
        sum[p] = t * t;
      }
      for (uint32_t j = 1; j < d; ++j) {
        const F c = *reinterpret_cast<const Unaligned*>(group + j * kLanes + part * W);
        for (int p = 0; p < P; ++p) {
          const F t = c - MLCLUST_POINT(p, j);
          sum[p] = t * t + sum[p];
        }
      }
      for (int p = 0; p < P; ++p) {
        const I closer = sum[p] < best[p][part];
        best[p][part] = closer ? sum[p] : best[p][part];
        best_id[p][part] = closer ? id[part] : best_id[p][part];
      }
      id[part] += kLanes;
    }
  }
#undef MLCLUST_POINT
  // Across lanes, without branches (which lane wins is unpredictable): the smallest value,
  // then the smallest id among the lanes that hold it.
  for (int p = 0; p < P; ++p) {
    F value = best[p][0];
    I index = best_id[p][0];
    for (int part = 1; part < kParts; ++part) {
      const I take =
          (best[p][part] < value) | ((best[p][part] == value) & (best_id[p][part] < index));
      value = take ? best[p][part] : value;
      index = take ? best_id[p][part] : index;
    }
    F low = value;
    MinAcrossLanes<W>(low);
    I id_low = value == low ? index : I{} + std::numeric_limits<int32_t>::max();
    MinAcrossLanes<W>(id_low);
    nearest[p] = static_cast<uint32_t>(id_low[0]);
  }
}

template <int W, int D>
MLCLUST_INLINE void NearestOfRange(const float* x, size_t count, uint32_t dims, const float* groups,
                                   uint32_t num_groups, uint32_t* nearest) {
  size_t i = 0;
  for (; i + 4 <= count; i += 4) {
    NearestOfGroup<W, D, 4>(x + i * dims, dims, groups, num_groups, nearest + i);
  }
  for (; i < count; ++i)
    NearestOfGroup<W, D, 1>(x + i * dims, dims, groups, num_groups, nearest + i);
}

// sum = the squared distances of the W points in vector v of a transposed run (see
// CandidatePotentials) to `centre` (d floats).
// (The vector types come from Vec<W>: deduced from an argument, Unaligned would lose its
// alignment attribute.)
template <int W, int kVectors>
MLCLUST_INLINE void RunDistances(const typename Vec<W>::Unaligned* coordinates, int v, uint32_t d,
                                 const float* centre, typename Vec<W>::F& sum) {
  using F = typename Vec<W>::F;
  const F t0 = coordinates[v] - centre[0];
  sum = t0 * t0;
  for (uint32_t j = 1; j < d; ++j) {
    const F t = coordinates[j * kVectors + v] - centre[j];
    sum = t * t + sum;
  }
}

// For each of the `num_candidates` candidates (rows of d floats) and each point i of
// `num_runs` runs of kRun points: adds min(||x_i - candidate||^2, closest_i) to
// sums[candidate] (double). First lowers closest_i to the squared distance to `pending`
// where given. Vectorised over points: a run is stored transposed (run r holds, for each
// dimension j, the j-th coordinates of its kRun points side by side), so one vector holds
// one coordinate of W points. Padding points past m have closest 0 and add nothing.
template <int W, int D>
MLCLUST_INLINE void CandidatePotentials(const float* runs, size_t num_runs, uint32_t dims,
                                        const float* pending, float* closest,
                                        const float* candidates, uint32_t num_candidates,
                                        double* sums) {
  using F = typename Vec<W>::F;
  using Unaligned = typename Vec<W>::Unaligned;
  typedef double Double4 __attribute__((vector_size(32)));
  constexpr int kVectors = kRun / W;
  const uint32_t d = D > 0 ? D : dims;
  // Float sums over one run, then double lanes (no long chain of scalar additions).
  Double4 totals[kMaxCandidates * (W / 4)];
  for (uint32_t c = 0; c < num_candidates * (W / 4); ++c) totals[c] = Double4{};
  for (size_t r = 0; r < num_runs; ++r) {
    const Unaligned* coordinates = reinterpret_cast<const Unaligned*>(runs + r * d * kRun);
    Unaligned* run_closest = reinterpret_cast<Unaligned*>(closest + r * kRun);
    F near[kVectors];
    for (int v = 0; v < kVectors; ++v) near[v] = run_closest[v];
    if (pending != nullptr) {
      for (int v = 0; v < kVectors; ++v) {
        F sum;
        RunDistances<W, kVectors>(coordinates, v, d, pending, sum);
        near[v] = sum < near[v] ? sum : near[v];
        run_closest[v] = near[v];
      }
    }
    for (uint32_t c = 0; c < num_candidates; ++c) {
      const float* candidate = candidates + size_t{c} * d;
      F total = F{};
      for (int v = 0; v < kVectors; ++v) {
        F sum;
        RunDistances<W, kVectors>(coordinates, v, d, candidate, sum);
        total += sum < near[v] ? sum : near[v];
      }
      if constexpr (W == 8) {
        totals[2 * c] +=
            __builtin_convertvector(__builtin_shufflevector(total, total, 0, 1, 2, 3), Double4);
        totals[2 * c + 1] +=
            __builtin_convertvector(__builtin_shufflevector(total, total, 4, 5, 6, 7), Double4);
      } else {
        totals[c] += __builtin_convertvector(total, Double4);
      }
    }
  }
  for (uint32_t c = 0; c < num_candidates; ++c) {
    for (int part = 0; part < W / 4; ++part) {
      const Double4 lanes = totals[c * (W / 4) + part];
      sums[c] += (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]);
    }
  }
}

#define MLCLUST_DISPATCH_DIMS(W, FUNCTION, dims, ...) \
  switch (dims) {                                     \
    case 1:                                           \
      FUNCTION<W, 1>(__VA_ARGS__);                    \
      break;                                          \
    case 2:                                           \
      FUNCTION<W, 2>(__VA_ARGS__);                    \
      break;                                          \
    case 3:                                           \
      FUNCTION<W, 3>(__VA_ARGS__);                    \
      break;                                          \
    case 4:                                           \
      FUNCTION<W, 4>(__VA_ARGS__);                    \
      break;                                          \
    default:                                          \
      FUNCTION<W, 0>(__VA_ARGS__);                    \
  }

void NearestBaseline(const float* x, size_t count, uint32_t dims, const float* groups,
                     uint32_t num_groups, uint32_t* nearest) {
  MLCLUST_DISPATCH_DIMS(4, NearestOfRange, dims, x, count, dims, groups, num_groups, nearest);
}
void CandidatesBaseline(const float* runs, size_t num_runs, uint32_t dims, const float* pending,
                        float* closest, const float* candidates, uint32_t num_candidates,
                        double* sums) {
  MLCLUST_DISPATCH_DIMS(4, CandidatePotentials, dims, runs, num_runs, dims, pending, closest,
                        candidates, num_candidates, sums);
}

using NearestFunction = void (*)(const float*, size_t, uint32_t, const float*, uint32_t, uint32_t*);
using CandidatesFunction = void (*)(const float*, size_t, uint32_t, const float*, float*,
                                    const float*, uint32_t, double*);

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
__attribute__((target("avx2,fma"))) void NearestAvx2(const float* x, size_t count, uint32_t dims,
                                                     const float* groups, uint32_t num_groups,
                                                     uint32_t* nearest) {
  MLCLUST_DISPATCH_DIMS(8, NearestOfRange, dims, x, count, dims, groups, num_groups, nearest);
}
__attribute__((target("avx2,fma"))) void CandidatesAvx2(const float* runs, size_t num_runs,
                                                        uint32_t dims, const float* pending,
                                                        float* closest, const float* candidates,
                                                        uint32_t num_candidates, double* sums) {
  MLCLUST_DISPATCH_DIMS(8, CandidatePotentials, dims, runs, num_runs, dims, pending, closest,
                        candidates, num_candidates, sums);
}
std::atomic<bool> force_baseline{false};
bool HasAvx2() {
  static const bool has = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  return has && !force_baseline.load(std::memory_order_relaxed);
}
NearestFunction NearestKernel() { return HasAvx2() ? NearestAvx2 : NearestBaseline; }
CandidatesFunction CandidatesKernel() { return HasAvx2() ? CandidatesAvx2 : CandidatesBaseline; }
#else
std::atomic<bool> force_baseline{false};
NearestFunction NearestKernel() { return NearestBaseline; }
CandidatesFunction CandidatesKernel() { return CandidatesBaseline; }
#endif

// Lays out k centres (k x d, row-major) as groups of kLanes (see kLanes).
template <typename T>
void FillGroups(const T* centres, uint32_t k, uint32_t d, std::vector<float>& groups) {
  const uint32_t num_groups = (k + kLanes - 1) / kLanes;
  groups.assign(size_t{num_groups} * d * kLanes, std::numeric_limits<float>::infinity());
  for (uint32_t c = 0; c < k; ++c) {
    float* group = groups.data() + size_t{c / kLanes} * d * kLanes + c % kLanes;
    for (uint32_t j = 0; j < d; ++j)
      group[j * kLanes] = static_cast<float>(centres[size_t{c} * d + j]);
  }
}

// Lloyd's assignment step on the CPU: the float kernel above, block by block.
class CpuLloydAssign final : public detail::LloydAssignStage {
 public:
  explicit CpuLloydAssign(const PointSet& points) : points_(points), kernel_(NearestKernel()) {}

  absl::Status SetCentres(std::span<const double> centres) override {
    const uint32_t d = points_.dims;
    const auto k = static_cast<uint32_t>(centres.size() / d);
    num_groups_ = (k + kLanes - 1) / kLanes;
    FillGroups(centres.data(), k, d, groups_);
    return absl::OkStatus();
  }

  const uint32_t* Nearest(size_t begin, size_t end, uint32_t* scratch) const override {
    const uint32_t d = points_.dims;
    kernel_(points_.values.data() + begin * d, end - begin, d, groups_.data(), num_groups_,
            scratch);
    return scratch;
  }

 private:
  const PointSet& points_;
  const NearestFunction kernel_;
  std::vector<float> groups_;
  uint32_t num_groups_ = 0;
};

double SquaredDistance(const float* x, const double* c, uint32_t d) {
  double sum = 0;
  for (uint32_t j = 0; j < d; ++j) {
    const double t = x[j] - c[j];
    sum += t * t;
  }
  return sum;
}

// ---------------------------------------------------------------------------------------
// Checks and statistics shared by the entry points.

// After ValidatePoints.
absl::Status CheckClustersAndThreads(const PointSet& points, uint64_t k, int threads) {
  const size_t m = points.num_points();
  if (k < 1 || k > m) {
    return absl::InvalidArgumentError(
        absl::StrCat("clusters: k = ", k, " is outside [1, ", m, "] (the number of points)"));
  }
  if (threads < 0) return absl::InvalidArgumentError(absl::StrCat("threads: ", threads, " < 0"));
  return absl::OkStatus();
}

struct PointStats {
  std::vector<float> low, high;  // bounding box
  double mean_variance = 0;      // mean over dimensions of the variance
};

// Deterministic: per-block sums added in block order.
PointStats ComputeStats(const PointSet& points, tbb::task_arena& arena) {
  const size_t m = points.num_points();
  const uint32_t d = points.dims;
  const size_t num_blocks = NumBlocks(m);
  std::vector<double> block_sums(num_blocks * d, 0.0);
  std::vector<float> block_low(num_blocks * d), block_high(num_blocks * d);
  arena.execute([&] {
    tbb::parallel_for(size_t{0}, num_blocks, [&](size_t b) {
      double* sum = &block_sums[b * d];
      float* low = &block_low[b * d];
      float* high = &block_high[b * d];
      const float* first = points.values.data() + BlockBegin(b) * d;
      std::copy(first, first + d, low);
      std::copy(first, first + d, high);
      for (size_t i = BlockBegin(b); i < BlockEnd(b, m); ++i) {
        const float* x = points.values.data() + i * d;
        for (uint32_t j = 0; j < d; ++j) {
          sum[j] += x[j];
          low[j] = std::min(low[j], x[j]);
          high[j] = std::max(high[j], x[j]);
        }
      }
    });
  });
  PointStats stats;
  stats.low.assign(block_low.begin(), block_low.begin() + d);
  stats.high.assign(block_high.begin(), block_high.begin() + d);
  std::vector<double> mean(d, 0.0);
  for (size_t b = 0; b < num_blocks; ++b) {
    for (uint32_t j = 0; j < d; ++j) {
      mean[j] += block_sums[b * d + j];
      stats.low[j] = std::min(stats.low[j], block_low[b * d + j]);
      stats.high[j] = std::max(stats.high[j], block_high[b * d + j]);
    }
  }
  for (double& v : mean) v /= static_cast<double>(m);
  std::vector<double> block_squares(num_blocks, 0.0);
  arena.execute([&] {
    tbb::parallel_for(size_t{0}, num_blocks, [&](size_t b) {
      double sum = 0;
      for (size_t i = BlockBegin(b); i < BlockEnd(b, m); ++i) {
        sum += SquaredDistance(points.values.data() + i * d, mean.data(), d);
      }
      block_squares[b] = sum;
    });
  });
  double squares = 0;
  for (double s : block_squares) squares += s;
  stats.mean_variance = squares / static_cast<double>(m) / d;
  return stats;
}

absl::Status CheckExtent(const std::vector<float>& low, const std::vector<float>& high) {
  for (size_t j = 0; j < low.size(); ++j) {
    const double extent = static_cast<double>(high[j]) - low[j];
    if (extent > kMaxExtent) {
      return absl::InvalidArgumentError(absl::StrCat("points: coordinate ", j, " spans ", extent,
                                                     ", over the ", kMaxExtent,
                                                     " that k-means' float distances allow"));
    }
  }
  return absl::OkStatus();
}

tbb::task_arena MakeArena(int threads) {
  return tbb::task_arena(threads > 0 ? threads : tbb::task_arena::automatic);
}

// ---------------------------------------------------------------------------------------
// Greedy k-means++.

// CANCELLED if `cancel` is set (checked before each centre).
absl::StatusOr<std::vector<float>> PlusPlus(const PointSet& points, uint32_t k, uint64_t seed,
                                            tbb::task_arena& arena,
                                            const std::atomic<bool>* cancel) {
  const size_t m = points.num_points();
  const uint32_t d = points.dims;
  const float* values = points.values.data();
  const size_t num_blocks = NumBlocks(m);
  // scikit-learn's choice: "2 + log(k)" trials, which Arthur & Vassilvitskii found to help.
  const uint32_t trials = 2 + static_cast<uint32_t>(std::log(static_cast<double>(k)));
  Random random(seed);

  std::vector<float> centres(size_t{k} * d);
  auto take = [&](uint32_t c, size_t point) {
    std::copy(values + point * d, values + (point + 1) * d, centres.begin() + size_t{c} * d);
  };
  take(0, random.Below(m));
  // The points, transposed in runs (see CandidatePotentials): each step reads every point
  // once per candidate, and transposing once costs m d floats but halves the time of a step.
  const size_t num_runs = (m + kRun - 1) / kRun;
  std::vector<float> runs(num_runs * kRun * d, 0.0f);
  // closest[i]: squared distance from point i to its nearest centre, except that the newest
  // centre (`pending`) is folded in lazily, by the next pass over the points or while
  // sampling; 0 for the padding past m. block_potential[b] is exact: the sum over block b
  // with `pending` folded in.
  std::vector<float> closest(num_runs * kRun, 0.0f);
  std::vector<double> block_potential(num_blocks);
  arena.execute([&] {
    tbb::parallel_for(size_t{0}, num_runs, [&](size_t r) {
      float* run = &runs[r * kRun * d];
      for (size_t i = r * kRun; i < std::min(m, (r + 1) * kRun); ++i) {
        for (uint32_t j = 0; j < d; ++j) run[j * kRun + i % kRun] = values[i * d + j];
        closest[i] = std::numeric_limits<float>::infinity();
      }
    });
  });
  const CandidatesFunction candidates_kernel = CandidatesKernel();
  const float* pending = nullptr;
  // One pass over the points: block_sums[b * count + t] = sum over block b of
  // min(closest, distance to candidate t), with `pending` folded in first.
  auto potentials = [&](const float* candidates, uint32_t count, std::vector<double>& block_sums) {
    arena.execute([&] {
      tbb::parallel_for(size_t{0}, num_blocks, [&](size_t b) {
        double* sums = &block_sums[b * count];
        std::fill(sums, sums + count, 0.0);
        const size_t first_run = b * (kBlock / kRun);
        const size_t end_run = std::min(num_runs, (b + 1) * (kBlock / kRun));
        candidates_kernel(&runs[first_run * kRun * d], end_run - first_run, d, pending,
                          &closest[first_run * kRun], candidates, count, sums);
      });
    });
  };
  // The first centre as the single candidate: closest starts at +inf, so the sums are the
  // block potentials, and the centre is pending.
  potentials(centres.data(), 1, block_potential);
  pending = centres.data();
  auto pending_closest = [&](size_t i) {
    float s = 0;
    for (uint32_t j = 0; j < d; ++j) {
      const float t = values[i * d + j] - pending[j];
      s += t * t;
    }
    return std::min(closest[i], s);
  };
  // Draws a point with probability proportional to its (lazily updated) closest distance:
  // the first whose running sum passes the target, within the block whose does.
  auto sample = [&](double potential) -> size_t {
    if (!(potential > 0)) return random.Below(m);  // every point sits on a centre
    const double target = random.Unit() * potential;
    double before = 0;
    size_t block = num_blocks;
    for (size_t b = 0; b < num_blocks; ++b) {
      if (block_potential[b] <= 0) continue;
      block = b;
      if (before + block_potential[b] > target) break;
      before += block_potential[b];
    }
    // Where rounding put the target past the end, the last positive point is taken.
    size_t chosen = m;
    for (size_t i = BlockBegin(block); i < BlockEnd(block, m); ++i) {
      const float s = pending_closest(i);
      if (s <= 0) continue;
      chosen = i;
      before += s;
      if (before > target) break;
    }
    return chosen;  // the block has a positive sum, so it holds a positive distance
  };

  std::vector<uint32_t> candidate(trials);
  std::vector<float> candidate_rows(size_t{trials} * d);
  std::vector<double> block_sums(num_blocks * trials);
  for (uint32_t c = 1; c < k; ++c) {
    MLCLUST_RETURN_IF_ERROR(CheckCancelled(cancel, "k-means++ seeding"));
    double potential = 0;
    for (double p : block_potential) potential += p;
    for (uint32_t t = 0; t < trials; ++t) {
      candidate[t] = static_cast<uint32_t>(sample(potential));
      std::copy(values + size_t{candidate[t]} * d, values + size_t{candidate[t] + 1} * d,
                candidate_rows.begin() + size_t{t} * d);
    }
    potentials(candidate_rows.data(), trials, block_sums);
    // The candidate that leaves the smallest potential (the first on ties).
    uint32_t best = 0;
    double best_potential = std::numeric_limits<double>::infinity();
    for (uint32_t t = 0; t < trials; ++t) {
      double sum = 0;
      for (size_t b = 0; b < num_blocks; ++b) sum += block_sums[b * trials + t];
      if (sum < best_potential) {
        best_potential = sum;
        best = t;
      }
    }
    for (size_t b = 0; b < num_blocks; ++b) {
      block_potential[b] = block_sums[b * trials + best];
    }
    take(c, candidate[best]);
    pending = centres.data() + size_t{c} * d;
  }
  return centres;
}

// ---------------------------------------------------------------------------------------
// Lloyd.

// CANCELLED if options.cancel is set: checked by every block of points, which then skips
// its work (and its chunk's sums), and after each assignment.
absl::StatusOr<KmeansResult> Lloyd(const PointSet& points, std::vector<double> centres,
                                   const KmeansOptions& options, double mean_variance,
                                   tbb::task_arena& arena, detail::LloydAssignStage& assign) {
  const auto start = std::chrono::steady_clock::now();
  const size_t m = points.num_points();
  const uint32_t d = points.dims;
  const uint32_t k = static_cast<uint32_t>(centres.size() / d);
  const float* values = points.values.data();
  const size_t num_blocks = NumBlocks(m);
  const size_t row = size_t{d} + 1;  // per-cluster sums: d coordinates and the count
  // Per-cluster sums are kept per chunk of consecutive blocks and added in chunk order. Up to
  // 64 chunks (parallel accumulation), within a budget of 32 MiB of sums where k d is large;
  // within a chunk, assignment stays parallel over its blocks.
  const size_t budget = (size_t{32} << 20) / sizeof(double);
  const size_t max_chunks = std::clamp<size_t>(budget / (row * k), 1, 64);
  const size_t blocks_per_chunk = (num_blocks + max_chunks - 1) / max_chunks;
  const size_t num_chunks = (num_blocks + blocks_per_chunk - 1) / blocks_per_chunk;
  const double tolerance = options.tolerance * mean_variance;

  std::vector<uint32_t> labels(m, 0);
  std::vector<double> chunk_sums(num_chunks * k * row);
  std::vector<double> sums(size_t{k} * row);
  std::vector<double> block_energy(num_blocks);
  std::vector<uint64_t> block_moves(num_blocks);
  std::vector<double> distance;          // per point, only when a cluster empties
  std::vector<uint8_t> relocated(k, 0);  // clusters reseeded in this iteration
  KmeansResult result;

  for (uint32_t iteration = 1; iteration <= options.max_iterations; ++iteration) {
    const bool first = iteration == 1;
    MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "Lloyd iteration"));
    MLCLUST_RETURN_IF_ERROR(assign.SetCentres(centres));
    // Assignment (parallel over blocks), then the chunk's sums.
    arena.execute([&] {
      tbb::parallel_for(size_t{0}, num_chunks, [&](size_t chunk) {
        const size_t first_block = chunk * blocks_per_chunk;
        const size_t last_block = std::min(num_blocks, first_block + blocks_per_chunk);
        std::atomic<bool> skipped{false};
        tbb::parallel_for(first_block, last_block, [&](size_t b) {
          if (IsCancelled(options.cancel)) {
            skipped.store(true, std::memory_order_relaxed);
            return;
          }
          uint32_t scratch[kBlock];
          const size_t begin = BlockBegin(b);
          const size_t end = BlockEnd(b, m);
          const uint32_t* proposed = assign.Nearest(begin, end, scratch);
          double energy = 0;
          uint64_t moves = 0;
          for (size_t i = begin; i < end; ++i) {
            const float* x = values + i * d;
            uint32_t label = proposed[i - begin];
            double s = SquaredDistance(x, &centres[size_t{label} * d], d);
            if (!first && label != labels[i]) {
              // The float kernel may be off on near-ties; a point moves only where the move
              // lowers its double-precision distance, so the energy never rises.
              const double current = SquaredDistance(x, &centres[size_t{labels[i]} * d], d);
              if (s < current) {
                ++moves;
              } else {
                label = labels[i];
                s = current;
              }
            }
            labels[i] = label;
            energy += s;
          }
          block_energy[b] = energy;
          block_moves[b] = first ? end - begin : moves;
        });
        if (skipped.load()) return;  // labels of the skipped blocks are not set
        double* local = &chunk_sums[chunk * k * row];
        std::fill(local, local + k * row, 0.0);
        for (size_t i = BlockBegin(first_block); i < BlockEnd(last_block - 1, m); ++i) {
          double* cluster = local + size_t{labels[i]} * row;
          const float* x = values + i * d;
          for (uint32_t j = 0; j < d; ++j) cluster[j] += x[j];
          cluster[d] += 1;
        }
      });
      tbb::parallel_for(tbb::blocked_range<uint32_t>(0, k, 256),
                        [&](const tbb::blocked_range<uint32_t>& range) {
                          for (uint32_t c = range.begin(); c != range.end(); ++c) {
                            double* total = &sums[size_t{c} * row];
                            std::fill(total, total + row, 0.0);
                            for (size_t chunk = 0; chunk < num_chunks; ++chunk) {
                              const double* part = &chunk_sums[(chunk * k + c) * row];
                              for (size_t j = 0; j < row; ++j) total[j] += part[j];
                            }
                          }
                        });
    });
    // Skipped blocks left stale labels and sums: nothing after this may use them.
    MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "Lloyd iteration"));
    double energy = 0;  // of the new labels against the centres they were assigned to
    uint64_t moves = 0;
    for (size_t b = 0; b < num_blocks; ++b) {
      energy += block_energy[b];
      moves += block_moves[b];
    }

    // Empty clusters: each takes the point farthest from its centre among clusters that keep
    // at least one point (scikit-learn's _relocate_empty_clusters). The point then sits on
    // its new centre, so the energy falls by its distance.
    std::fill(relocated.begin(), relocated.end(), 0);
    bool have_distances = false;
    for (uint32_t empty = 0; empty < k; ++empty) {
      if (sums[size_t{empty} * row + d] > 0) continue;
      if (!have_distances) {
        distance.resize(m);
        arena.execute([&] {
          tbb::parallel_for(size_t{0}, m, [&](size_t i) {
            distance[i] = SquaredDistance(values + i * d, &centres[size_t{labels[i]} * d], d);
          });
        });
        have_distances = true;
      }
      // Farthest eligible point, ties to the smaller id (a deterministic reduction).
      using Best = std::pair<double, size_t>;  // distance, point (m: none)
      const Best none{-1.0, m};
      const Best far = arena.execute([&] {
        return tbb::parallel_reduce(
            tbb::blocked_range<size_t>(0, m, kBlock), none,
            [&](const tbb::blocked_range<size_t>& range, Best best) {
              for (size_t i = range.begin(); i != range.end(); ++i) {
                if (distance[i] > best.first && sums[size_t{labels[i]} * row + d] > 1) {
                  best = {distance[i], i};
                }
              }
              return best;
            },
            [](const Best& a, const Best& b) {
              if (a.first != b.first) return a.first > b.first ? a : b;
              return a.second < b.second ? a : b;
            });
      });
      // k <= m leaves at least as many spare points as empty clusters.
      const size_t i = far.second;
      const float* x = values + i * d;
      double* from = &sums[size_t{labels[i]} * row];
      double* to = &sums[size_t{empty} * row];
      for (uint32_t j = 0; j < d; ++j) {
        from[j] -= x[j];
        to[j] = x[j];
      }
      from[d] -= 1;
      to[d] = 1;
      energy -= distance[i];
      distance[i] = -1;  // sits on a centre now, and alone in its cluster
      labels[i] = empty;
      relocated[empty] = 1;
      ++moves;
    }

    // New centres: the means. The energy of the labels against their means follows from
    // that against the old centres: sum_{x in c} ||x - old||^2 = sum ||x - mean||^2 +
    // n_c ||mean - old||^2.
    double shift = 0;
    double correction = 0;
    for (uint32_t c = 0; c < k; ++c) {
      const double* total = &sums[size_t{c} * row];
      double* centre = &centres[size_t{c} * d];
      double moved = 0;
      for (uint32_t j = 0; j < d; ++j) {
        const double mean = total[j] / total[d];
        const double t = mean - centre[j];
        moved += t * t;
        centre[j] = mean;
      }
      shift += moved;
      if (!relocated[c]) correction += total[d] * moved;
    }
    // A relocated cluster's shift is measured from the old centre, but its point's energy
    // was already taken out at its own position: no correction for it.
    result.inertia = std::max(0.0, energy - correction);
    result.iterations = iteration;
    if (first && options.keep_first_assignment) {
      result.first_labels.resize(m);
      for (size_t i = 0; i < m; ++i) result.first_labels[i] = ClusterId(labels[i]);
      result.first_inertia = result.inertia;
    }
    if (options.on_iteration) options.on_iteration(iteration, result.inertia);
    if ((!first && moves == 0) || shift <= tolerance) {
      result.converged = true;
      break;
    }
  }

  result.labels.resize(m);
  for (size_t i = 0; i < m; ++i) result.labels[i] = ClusterId(labels[i]);
  result.centres.assign(centres.begin(), centres.end());
  result.seconds_iterations = Seconds(start);
  return result;
}

absl::Status CheckLloydOptions(const KmeansOptions& options) {
  if (options.max_iterations < 1) {
    return absl::InvalidArgumentError("max_iterations: 0; at least 1 iteration is needed");
  }
  if (!(options.tolerance >= 0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("tolerance: ", options.tolerance, " is not >= 0"));
  }
  return absl::OkStatus();
}

}  // namespace

namespace detail {
void SetKmeansKernelsForTesting(KmeansKernels kernels) {
  force_baseline.store(kernels == KmeansKernels::kBaseline, std::memory_order_relaxed);
}
}  // namespace detail

absl::StatusOr<std::vector<float>> KmeansPlusPlusCentres(const PointSet& points, uint32_t k,
                                                         uint64_t seed, int threads) {
  MLCLUST_RETURN_IF_ERROR(ValidatePoints(points));
  MLCLUST_RETURN_IF_ERROR(CheckClustersAndThreads(points, k, threads));
  tbb::task_arena arena = MakeArena(threads);
  const PointStats stats = ComputeStats(points, arena);
  MLCLUST_RETURN_IF_ERROR(CheckExtent(stats.low, stats.high));
  return PlusPlus(points, k, seed, arena, nullptr);
}

absl::StatusOr<KmeansResult> RunKmeans(const PointSet& points, const KmeansOptions& options) {
  MLCLUST_RETURN_IF_ERROR(ValidatePoints(points));
  MLCLUST_RETURN_IF_ERROR(CheckClustersAndThreads(points, options.clusters, options.threads));
  MLCLUST_RETURN_IF_ERROR(CheckLloydOptions(options));
  tbb::task_arena arena = MakeArena(options.threads);
  const PointStats stats = ComputeStats(points, arena);
  MLCLUST_RETURN_IF_ERROR(CheckExtent(stats.low, stats.high));

  const auto start = std::chrono::steady_clock::now();
  const uint32_t k = options.clusters;
  const uint32_t d = points.dims;
  std::vector<double> centres(size_t{k} * d);
  if (options.init == KmeansOptions::Init::kKmeansPlusPlus) {
    MLCLUST_ASSIGN_OR_RETURN(const std::vector<float> seeds,
                             PlusPlus(points, k, options.seed, arena, options.cancel));
    centres.assign(seeds.begin(), seeds.end());
  } else {
    // k distinct points: the first k of a partial Fisher-Yates shuffle.
    const size_t m = points.num_points();
    std::vector<uint32_t> order(m);
    for (size_t i = 0; i < m; ++i) order[i] = static_cast<uint32_t>(i);
    Random random(options.seed);
    for (uint32_t c = 0; c < k; ++c) {
      std::swap(order[c], order[c + random.Below(m - c)]);
      for (uint32_t j = 0; j < d; ++j) {
        centres[size_t{c} * d + j] = points.values[size_t{order[c]} * d + j];
      }
    }
  }
  const double seconds_init = Seconds(start);
  CpuLloydAssign assign(points);
  MLCLUST_ASSIGN_OR_RETURN(KmeansResult result, Lloyd(points, std::move(centres), options,
                                                      stats.mean_variance, arena, assign));
  result.seconds_init = seconds_init;
  return result;
}

absl::StatusOr<KmeansResult> RunLloyd(const PointSet& points, std::vector<float> centres,
                                      const KmeansOptions& options) {
  CpuLloydAssign assign(points);
  return detail::RunLloydWithAssign(points, std::move(centres), options, assign);
}

absl::StatusOr<KmeansResult> detail::RunLloydWithAssign(const PointSet& points,
                                                        std::vector<float> centres,
                                                        const KmeansOptions& options,
                                                        LloydAssignStage& assign) {
  MLCLUST_RETURN_IF_ERROR(ValidatePoints(points));
  const uint32_t d = points.dims;
  if (centres.empty() || centres.size() % d != 0) {
    return absl::InvalidArgumentError(absl::StrCat("centres: ", centres.size(),
                                                   " values are not a whole number of ", d,
                                                   "-dimensional centres"));
  }
  const uint64_t k = centres.size() / d;
  if (options.clusters != 0 && options.clusters != k) {
    return absl::InvalidArgumentError(
        absl::StrCat("centres: ", k, " centres given but options.clusters = ", options.clusters));
  }
  MLCLUST_RETURN_IF_ERROR(CheckClustersAndThreads(points, k, options.threads));
  MLCLUST_RETURN_IF_ERROR(CheckLloydOptions(options));
  for (size_t i = 0; i < centres.size(); ++i) {
    if (!std::isfinite(centres[i])) {
      return absl::InvalidArgumentError(
          absl::StrCat("centres: centre ", i / d, " coordinate ", i % d, " is ", centres[i]));
    }
  }
  tbb::task_arena arena = MakeArena(options.threads);
  PointStats stats = ComputeStats(points, arena);
  for (size_t i = 0; i < centres.size(); ++i) {
    stats.low[i % d] = std::min(stats.low[i % d], centres[i]);
    stats.high[i % d] = std::max(stats.high[i % d], centres[i]);
  }
  MLCLUST_RETURN_IF_ERROR(CheckExtent(stats.low, stats.high));
  return Lloyd(points, std::vector<double>(centres.begin(), centres.end()), options,
               stats.mean_variance, arena, assign);
}

}  // namespace mlclust
