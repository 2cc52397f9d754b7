#include "gpu/stages/point_stages_gpu.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"
#include "core/base/renumber.h"
#include "core/base/status_macros.h"
#include "core/cluster/detail/ln_kmeans_stages.h"
#include "gpu/kernels/kmeans_assign.h"
#include "gpu/kernels/ln_kmeans.h"
#include "tbb/parallel_for.h"
#include "tbb/task_arena.h"

namespace mlclust::gpu {
namespace {

// Points per block of RunLloydGpu's host work (at least; more with many clusters).
constexpr size_t kBlock = 65536;

// The counts of a PointClusters as the kernel reads them (a count is below 2^31 points).
void Counts(const mlclust::detail::PointClusters& clusters, std::vector<uint32_t>& counts) {
  counts.resize(clusters.capacity());
  for (uint32_t c = 0; c < clusters.capacity(); ++c) {
    counts[c] = static_cast<uint32_t>(clusters.count(c));
  }
}

double SquaredDistance(const float* x, const double* centre, uint32_t d) {
  double sum = 0;
  for (uint32_t j = 0; j < d; ++j) {
    const double diff = static_cast<double>(x[j]) - centre[j];
    sum += diff * diff;
  }
  return sum;
}

}  // namespace

absl::StatusOr<LnKmeansResult> RunLnKmeansGpu(GlContext& context, const PointSet& points,
                                              std::vector<ClusterId> labels,
                                              const LnKmeansOptions& options) {
  MLCLUST_RETURN_IF_ERROR(ValidatePoints(points));
  const size_t m = points.num_points();
  if (labels.size() != m) {
    return absl::InvalidArgumentError(
        absl::StrCat("labels: ", labels.size(), " for ", m, " points"));
  }
  // Compact ids by first appearance, as RunLnKmeans does; the caller's come back.
  const Renumbering<ClusterId> compact =
      RenumberByFirstAppearance(std::span<const ClusterId>(labels));
  const uint32_t k = compact.size();
  mlclust::detail::PointClusters clusters(points, compact.dense, k);
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "LN k-means set-up"));
  MLCLUST_ASSIGN_OR_RETURN(LnKmeansKernel kernel,
                           LnKmeansKernel::Create(context, points, clusters.origin(), k));
  std::vector<uint32_t> counts;
  Counts(clusters, counts);
  MLCLUST_RETURN_IF_ERROR(
      kernel.SetClusters(clusters.centroids(), clusters.neighbour_table(), counts));
  MLCLUST_RETURN_IF_ERROR(kernel.InitialNeighbours(clusters.neighbour_table()));
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "LN k-means neighbours"));
  LnKmeansResult result;
  MLCLUST_RETURN_IF_ERROR(mlclust::detail::RunLnKmeansIterations(
      clusters, options, result,
      [&](const mlclust::detail::PointClusters& state, std::span<const uint32_t> check,
          std::span<uint32_t> target) -> absl::Status {
        Counts(state, counts);
        MLCLUST_RETURN_IF_ERROR(
            kernel.SetClusters(state.centroids(), state.neighbour_table(), counts));
        return kernel.Assign(state.labels(), check, target);
      }));
  result.labels.resize(m);
  for (size_t i = 0; i < m; ++i) result.labels[i] = compact.original[clusters.label(i)];
  return result;
}

absl::StatusOr<KmeansResult> RunLloydGpu(GlContext& context, const PointSet& points,
                                         std::vector<float> centres_in,
                                         const KmeansOptions& options) {
  MLCLUST_RETURN_IF_ERROR(ValidatePoints(points));
  const uint32_t d = points.dims;
  const size_t m = points.num_points();
  if (centres_in.empty() || centres_in.size() % d != 0) {
    return absl::InvalidArgumentError(absl::StrCat(
        "centres: ", centres_in.size(), " values are not a whole number of ", d, "-d points"));
  }
  const uint64_t k64 = centres_in.size() / d;
  if (k64 > m || (options.clusters != 0 && options.clusters != k64)) {
    return absl::InvalidArgumentError(absl::StrCat("clusters: ", k64, " centres for ", m,
                                                   " points (options.clusters ", options.clusters,
                                                   ")"));
  }
  for (float v : centres_in) {
    if (!std::isfinite(v)) return absl::InvalidArgumentError("centres: a value is not finite");
  }
  if (options.max_iterations == 0) {
    return absl::InvalidArgumentError("max_iterations: 0 (at least 1)");
  }
  if (!(options.tolerance >= 0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("tolerance: ", options.tolerance, " is not >= 0"));
  }
  const auto start = std::chrono::steady_clock::now();
  const uint32_t k = static_cast<uint32_t>(k64);
  const float* values = points.values.data();

  // The tolerance's scale: the mean over dimensions of the points' variance.
  std::vector<double> mean(d, 0.0);
  for (size_t i = 0; i < m; ++i) {
    for (uint32_t j = 0; j < d; ++j) mean[j] += values[i * d + j];
  }
  for (double& v : mean) v /= static_cast<double>(m);
  double squares = 0;
  for (size_t i = 0; i < m; ++i) squares += SquaredDistance(values + i * d, mean.data(), d);
  const double tolerance = options.tolerance * squares / static_cast<double>(m) / d;

  MLCLUST_ASSIGN_OR_RETURN(KmeansAssignKernel kernel,
                           KmeansAssignKernel::Create(context, points, k));
  std::vector<double> centres(centres_in.begin(), centres_in.end());
  std::vector<float> upload(centres_in.size());
  std::vector<uint32_t> labels(m, 0), nearest(m);
  std::vector<double> sums(size_t{k} * (d + 1)), distance;
  // Per-block partial sums: k (d + 1) doubles per block of kBlock points, so with many
  // clusters the blocks are fewer (at most 64 MiB of partials).
  const size_t row_values = size_t{k} * (d + 1);
  const size_t max_blocks = std::max<size_t>(1, (size_t{64} << 20) / (row_values * sizeof(double)));
  const size_t block_points = std::max<size_t>(kBlock, (m + max_blocks - 1) / max_blocks);
  const size_t blocks = (m + block_points - 1) / block_points;
  std::vector<double> partial(blocks * row_values), partial_energy(blocks);
  std::vector<uint64_t> partial_moves(blocks);
  tbb::task_arena arena(options.threads > 0 ? options.threads
                                            : static_cast<int>(tbb::task_arena::automatic));
  auto ParallelBlocks = [block_points, blocks](tbb::task_arena& on, size_t n, auto&& body) {
    on.execute([&] {
      tbb::parallel_for(size_t{0}, blocks, [&](size_t block) {
        const size_t begin = block * block_points;
        body(block, begin, std::min(n, begin + block_points));
      });
    });
  };
  KmeansResult result;
  for (uint32_t iteration = 1; iteration <= options.max_iterations; ++iteration) {
    MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "Lloyd iteration"));
    const bool first = iteration == 1;
    for (size_t v = 0; v < centres.size(); ++v) upload[v] = static_cast<float>(centres[v]);
    MLCLUST_RETURN_IF_ERROR(kernel.Assign(upload, nearest));
    // A point moves only where the move lowers its distance in double. Then the clusters'
    // sums. Both in blocks of kBlock points in parallel, the blocks' sums added in block
    // order, so the result does not depend on the thread count.
    ParallelBlocks(arena, m, [&](size_t block, size_t begin, size_t end) {
      uint64_t block_moves = 0;
      double* block_sums = &partial[block * row_values];
      std::fill(block_sums, block_sums + row_values, 0.0);
      for (size_t i = begin; i < end; ++i) {
        const float* x = values + i * d;
        if (first || (nearest[i] != labels[i] &&
                      SquaredDistance(x, &centres[size_t{nearest[i]} * d], d) <
                          SquaredDistance(x, &centres[size_t{labels[i]} * d], d))) {
          block_moves += first || nearest[i] != labels[i];
          labels[i] = nearest[i];
        }
        double* sum = &block_sums[size_t{labels[i]} * (d + 1)];
        for (uint32_t j = 0; j < d; ++j) sum[j] += x[j];
        sum[d] += 1;
      }
      partial_moves[block] = block_moves;
    });
    uint64_t moves = 0;
    std::fill(sums.begin(), sums.end(), 0.0);
    for (size_t block = 0; block < blocks; ++block) {
      moves += partial_moves[block];
      const double* block_sums = &partial[block * row_values];
      for (size_t v = 0; v < row_values; ++v) sums[v] += block_sums[v];
    }
    // Empty clusters, in id order: the farthest point from its centre among clusters that
    // keep at least one point (ties to the smaller id).
    bool have_distances = false;
    for (uint32_t empty = 0; empty < k; ++empty) {
      if (sums[size_t{empty} * (d + 1) + d] > 0) continue;
      if (!have_distances) {
        distance.resize(m);
        for (size_t i = 0; i < m; ++i) {
          distance[i] = SquaredDistance(values + i * d, &centres[size_t{labels[i]} * d], d);
        }
        have_distances = true;
      }
      size_t far = m;
      double far_distance = -1;
      for (size_t i = 0; i < m; ++i) {
        if (distance[i] > far_distance && sums[size_t{labels[i]} * (d + 1) + d] > 1) {
          far_distance = distance[i];
          far = i;
        }
      }
      double* from = &sums[size_t{labels[far]} * (d + 1)];
      double* to = &sums[size_t{empty} * (d + 1)];
      for (uint32_t j = 0; j < d; ++j) {
        from[j] -= values[far * d + j];
        to[j] = values[far * d + j];
      }
      from[d] -= 1;
      to[d] = 1;
      distance[far] = -1;
      labels[far] = empty;
      ++moves;
    }
    double shift = 0;
    for (uint32_t c = 0; c < k; ++c) {
      const double* total = &sums[size_t{c} * (d + 1)];
      for (uint32_t j = 0; j < d; ++j) {
        const double mean_j = total[j] / total[d];
        const double t = mean_j - centres[size_t{c} * d + j];
        shift += t * t;
        centres[size_t{c} * d + j] = mean_j;
      }
    }
    ParallelBlocks(arena, m, [&](size_t block, size_t begin, size_t end) {
      double sum = 0;
      for (size_t i = begin; i < end; ++i) {
        sum += SquaredDistance(values + i * d, &centres[size_t{labels[i]} * d], d);
      }
      partial_energy[block] = sum;
    });
    double inertia = 0;
    for (size_t block = 0; block < blocks; ++block) inertia += partial_energy[block];
    result.inertia = inertia;
    result.iterations = iteration;
    if (options.on_iteration) options.on_iteration(iteration, inertia);
    if ((!first && moves == 0) || shift <= tolerance) {
      result.converged = true;
      break;
    }
  }
  result.labels.resize(m);
  for (size_t i = 0; i < m; ++i) result.labels[i] = ClusterId(labels[i]);
  result.centres.assign(centres.begin(), centres.end());
  result.seconds_iterations =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace mlclust::gpu
