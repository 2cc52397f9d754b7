#include "gpu/stages/points_multilevel_gpu.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <span>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"
#include "core/base/compensated_sum.h"
#include "core/base/status_macros.h"
#include "core/cluster/detail/local_neighbours.h"
#include "core/cluster/detail/point_levels_checks.h"
#include "core/cluster/device_stages.h"
#include "core/energy/variance_energy.h"
#include "gpu/kernels/points_levels.h"
#include "gpu/kernels/voxel_start.h"
#include "gpu/stages/gpu_level_sink.h"
#include "gpu/stages/points_optimise_gpu.h"

namespace mlclust::gpu {
namespace {

static_assert(kVoxelStartMaxDims == kGpuPointMaxDims);

constexpr uint32_t kNone = 0xFFFFFFFFu;
// The CPU's ConnectWhenStuck links the survivors only up to this many.
constexpr uint32_t kMaxLinked = 20000;

// The clusters of the voxel start as the CPU's PointSpace builds them.
struct Start {
  std::vector<uint32_t> counts;
  std::vector<double> sums;       // k x (d + 1)
  std::vector<double> centroids;  // k x d
  std::vector<uint32_t> neighbours;
  std::vector<double> origin;  // d: the data's mean the sums are relative to
  double energy = 0;
};

// PointClusters::RefreshNeighbours on the flat tables (detail::RefreshLocalNeighbours, the
// CPU's own).
void RefreshNeighbours(Start& start, uint32_t d, uint32_t c, std::vector<uint32_t>& candidates,
                       ::mlclust::detail::LocalNeighbourScratch& scratch) {
  ::mlclust::detail::RefreshLocalNeighbours<uint32_t>(c, d, start.centroids, start.counts,
                                                      start.neighbours, candidates, scratch);
}

// PointSpace's constructor: points ordered by starting cell (stable), the data's mean
// and every cluster's sums in that order, the face-sharing neighbours refreshed one
// cluster after the other, isolated cells linked to the nearest in each subspace.
Start BuildStart(const PointSet& points, const VoxelStartGpuResult& voxels,
                 const std::atomic<bool>* cancel) {
  const uint32_t d = points.dims, k = voxels.clusters;
  const size_t m = points.num_points();
  std::vector<uint32_t> first(size_t{k} + 1, 0), order(m);
  for (const uint32_t c : voxels.labels) ++first[c + 1];
  for (uint32_t c = 0; c < k; ++c) first[c + 1] += first[c];
  for (size_t i = 0; i < m; ++i) order[first[voxels.labels[i]]++] = static_cast<uint32_t>(i);
  std::vector<double> origin(d, 0.0);
  for (size_t at = 0; at < m; ++at) {
    for (uint32_t j = 0; j < d; ++j) origin[j] += points.values[size_t{order[at]} * d + j];
  }
  for (double& o : origin) o /= static_cast<double>(std::max<size_t>(m, 1));
  Start start;
  start.counts.assign(k, 0);
  start.sums.assign(size_t{k} * (d + 1), 0.0);
  start.centroids.assign(size_t{k} * d, 0.0);
  for (size_t at = 0; at < m; ++at) {
    const size_t i = order[at];
    const uint32_t c = voxels.labels[i];
    double* sum = &start.sums[size_t{c} * (d + 1)];
    double s2 = 0;
    for (uint32_t j = 0; j < d; ++j) {
      const double v = points.values[i * d + j] - origin[j];
      sum[j] += v;
      s2 += v * v;
    }
    sum[d] += s2;
    ++start.counts[c];
  }
  double total = 0;  // TotalEnergy's plain sum in cluster order
  for (uint32_t c = 0; c < k; ++c) {
    const double n = static_cast<double>(start.counts[c]);
    for (uint32_t j = 0; j < d; ++j) {
      start.centroids[size_t{c} * d + j] = n > 0 ? start.sums[size_t{c} * (d + 1) + j] / n : 0.0;
    }
    total +=
        EnergyOfSums(n, {&start.sums[size_t{c} * (d + 1)], d}, start.sums[size_t{c} * (d + 1) + d]);
  }
  start.energy = total;
  start.origin = origin;
  start.neighbours = voxels.neighbours;
  std::vector<uint32_t> candidates;
  ::mlclust::detail::LocalNeighbourScratch scratch(k);
  for (uint32_t c = 0; c < k; ++c) {
    if (c % 4096 == 0 && IsCancelled(cancel)) return start;
    RefreshNeighbours(start, d, c, candidates, scratch);
  }
  std::vector<uint32_t> isolated;
  for (uint32_t c = 0; c < k; ++c) {
    const uint32_t* row = &start.neighbours[size_t{c} * 2 * d];
    if (std::all_of(row, row + 2 * d, [](uint32_t n) { return n == kNone; })) {
      isolated.push_back(c);
    }
  }
  for (const uint32_t c : isolated) {
    if (IsCancelled(cancel)) return start;
    for (uint32_t n = 0; n < k; ++n) {
      if (n != c) candidates.push_back(n);
    }
    RefreshNeighbours(start, d, c, candidates, scratch);
  }
  return start;
}

// Mesa's software renderers stop every loop of a shader invocation, without a word, once
// 65,535 iterations have run in it (all loops together; gpu/kernels/hc_levels.cc). One
// offer in points_refresh.glsl costs about 2d + 1 iterations; a cluster's refresh offers
// its 2d neighbours and theirs, twice when it kept a partner, and a cluster left without
// neighbours (or LinkAll) offers every one of the start's k0 clusters. Where that can pass
// the limit the run is refused on a software renderer rather than given short tables.
constexpr uint64_t kSoftwareLoopBudget = 60000;

absl::Status CheckSoftwareLoopBudget(const GlContext& context, uint32_t d, uint32_t k0) {
  if (!context.is_software()) return absl::OkStatus();
  const uint64_t offer = 2 * uint64_t{d} + 1, slots = 2 * uint64_t{d};
  const uint64_t around = 2 * slots * (slots + 1) * offer;
  const uint64_t all = uint64_t{k0} * offer;
  if (around <= kSoftwareLoopBudget && all <= kSoftwareLoopBudget) return absl::OkStatus();
  return absl::FailedPreconditionError(absl::StrCat(
      "PML for points on the GPU: ", d, " dimensions and ", k0, " start clusters need up to ",
      std::max(around, all),
      " loop iterations in one shader invocation, over what this software renderer runs (",
      "it stops an invocation's loops after 65,535); use --device cpu, or a hardware GPU"));
}

std::vector<ClusterId> AsClusterIds(std::span<const uint32_t> labels) {
  std::vector<ClusterId> ids(labels.size());
  for (size_t i = 0; i < labels.size(); ++i) ids[i] = ClusterId(labels[i]);
  return ids;
}

}  // namespace

std::string PointsPmlGpuUnsupported(const PointMultilevelOptions& options) {
  if (!options.parallel) return "only PML (parallel levels) runs on the GPU";
  if (options.optimizer != PointMultilevelOptions::Optimizer::kNone && options.bounded_drift > 0) {
    return "bounded-drift (ours) is the CPU's LN k-means'";
  }
  if (options.pml_until != 0) return "pml-until (the switch to ML) is not on the GPU";
  return "";
}

absl::StatusOr<PointMultilevelSummary> RunPointParallelMultilevelGpu(
    GlContext& context, const PointSet& points, const PointMultilevelOptions& options,
    LevelSink& sink) {
  MLCLUST_RETURN_IF_ERROR(::mlclust::detail::CheckPointLevelsArguments(points, options));
  const std::string unsupported = PointsPmlGpuUnsupported(options);
  if (!unsupported.empty()) {
    return absl::UnimplementedError(absl::StrCat("PML for points on the GPU: ", unsupported));
  }
  const uint32_t d = points.dims;
  MLCLUST_ASSIGN_OR_RETURN(VoxelStartGpuResult voxels,
                           VoxelGridStartGpu(context, points, options.grid, options.cancel));
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "the voxel start"));
  MLCLUST_RETURN_IF_ERROR(CheckSoftwareLoopBudget(context, d, voxels.clusters));
  Start start = BuildStart(points, voxels, options.cancel);
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "the voxel start's neighbours"));
  const uint32_t k0 = voxels.clusters;
  MLCLUST_RETURN_IF_ERROR(sink.OnStart(AsClusterIds(voxels.labels), k0, start.energy));
  if (options.inspect_level) options.inspect_level(0, voxels.labels);
  PointLevelsStart upload;
  upload.dims = d;
  upload.labels = voxels.labels;
  upload.counts = start.counts;
  upload.sums = start.sums;
  upload.centroids = start.centroids;
  upload.neighbours = start.neighbours;
  MLCLUST_ASSIGN_OR_RETURN(PointLevelsGpu levels, PointLevelsGpu::Create(context, upload));
  // LN k-means inside the levels (points_optimise_gpu.h): the host's mirror starts from the
  // values just uploaded.
  std::optional<PointLevelsOptimiser> optimiser;
  if (options.optimizer == PointMultilevelOptions::Optimizer::kLnKmeans) {
    PointOptimiserStart mirror{std::move(start.origin),    std::move(voxels.labels),
                               std::move(start.counts),    std::move(start.sums),
                               std::move(start.centroids), start.energy};
    MLCLUST_ASSIGN_OR_RETURN(PointLevelsOptimiser made,
                             PointLevelsOptimiser::Create(context, points, std::move(mirror),
                                                          options.optimise_rounds, options.cancel));
    optimiser.emplace(std::move(made));
  }
  std::vector<uint32_t>().swap(voxels.labels);
  PointMultilevelSummary summary;
  summary.levels = 1;
  summary.start_clusters = k0;
  summary.grid = voxels.cells_per_axis.empty() ? 0
                                               : *std::max_element(voxels.cells_per_axis.begin(),
                                                                   voxels.cells_per_axis.end());
  ::mlclust::detail::CompensatedSum energy;
  energy.Reset(start.energy);
  uint32_t clusters = k0;
  PointLevelGpu level;
  bool linked = false;
  while (clusters > options.min_clusters) {
    MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, absl::StrCat("level ", summary.levels)));
    MLCLUST_ASSIGN_OR_RETURN(
        const bool merged,
        optimiser.has_value()
            ? levels.MergeLevel(options.pml_pairs, clusters, options.min_clusters, level)
            : levels.Level(options.pml_pairs, clusters, options.min_clusters, level));
    if (!merged) {
      // No pair left: the CPU's ConnectWhenStuck links the survivors once they are few.
      if (linked || clusters <= 1 || clusters > kMaxLinked) break;
      MLCLUST_RETURN_IF_ERROR(levels.LinkAll());
      linked = true;
      continue;
    }
    linked = false;
    clusters -= level.merged;
    if (optimiser.has_value()) {
      // The level's LN k-means rounds and its report, then the neighbour refresh.
      MLCLUST_RETURN_IF_ERROR(optimiser->Level(levels, level, sink, summary.levels, clusters));
      MLCLUST_RETURN_IF_ERROR(levels.RefreshNeighbours());
      summary.moves = optimiser->moves();
    } else {
      energy.Add(level.energy_change);
      MLCLUST_RETURN_IF_ERROR(SendGpuLevel(level, summary.levels, clusters, energy.value(), sink));
      summary.moves += level.element.size();
    }
    if (options.inspect_level) {
      MLCLUST_ASSIGN_OR_RETURN(const std::vector<uint32_t> labels, levels.Labels());
      options.inspect_level(summary.levels, labels);
    }
    ++summary.levels;
  }
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, absl::StrCat("level ", summary.levels)));
  summary.final_clusters = clusters;
  return summary;
}

}  // namespace mlclust::gpu
