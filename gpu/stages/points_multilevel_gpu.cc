#include "gpu/stages/points_multilevel_gpu.h"

#include <algorithm>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"
#include "core/base/compensated_sum.h"
#include "core/base/status_macros.h"
#include "core/cluster/detail/ln_kmeans_stages.h"
#include "core/cluster/detail/point_levels_checks.h"
#include "core/plan/device_policy.h"
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

// PointSpace's constructor: the host's clusters of the voxel start in the CPU's order
// (MakePointLevelsHost), the face-sharing neighbours refreshed one cluster after the other,
// isolated cells linked to the nearest in each subspace. Stops early once `cancel` is set
// (the caller checks it).
std::unique_ptr<PointLevelsHost> BuildStart(const PointSet& points,
                                            const VoxelStartGpuResult& voxels,
                                            const std::atomic<bool>* cancel) {
  const uint32_t k = voxels.clusters;
  std::unique_ptr<PointLevelsHost> host = MakePointLevelsHost(points, voxels.labels, k);
  ::mlclust::detail::PointClusters& clusters = *host->clusters;
  std::copy(voxels.neighbours.begin(), voxels.neighbours.end(), clusters.neighbour_table().begin());
  std::vector<uint32_t> candidates;
  for (uint32_t c = 0; c < k; ++c) {
    if (c % 4096 == 0 && IsCancelled(cancel)) return host;
    clusters.RefreshNeighbours(c, candidates);
  }
  std::vector<uint32_t> isolated;
  for (uint32_t c = 0; c < k; ++c) {
    const std::span<const uint32_t> row = clusters.neighbours(c);
    if (std::all_of(row.begin(), row.end(), [](uint32_t n) { return n == kNone; })) {
      isolated.push_back(c);
    }
  }
  for (const uint32_t c : isolated) {
    if (IsCancelled(cancel)) return host;
    for (uint32_t n = 0; n < k; ++n) {
      if (n != c) candidates.push_back(n);
    }
    clusters.RefreshNeighbours(c, candidates);
  }
  return host;
}

// The software renderers' loop limit (kPointsSoftwareLoopBudget, points_levels.h): one
// offer in points_refresh.glsl costs about 2d + 1 iterations; a cluster's refresh offers
// its 2d neighbours and theirs, twice when it kept a partner, and a cluster left without
// neighbours (or LinkAll) offers every one of the start's k0 clusters. Where that can pass
// the limit the run is refused on a software renderer rather than given short tables.
absl::Status CheckSoftwareLoopBudget(const GlContext& context, uint32_t d, uint32_t k0) {
  if (!context.is_software()) return absl::OkStatus();
  const uint64_t offer = 2 * uint64_t{d} + 1, slots = 2 * uint64_t{d};
  const uint64_t around = 2 * slots * (slots + 1) * offer;
  const uint64_t all = uint64_t{k0} * offer;
  if (around <= kPointsSoftwareLoopBudget && all <= kPointsSoftwareLoopBudget)
    return absl::OkStatus();
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

// The start both loops share: the voxel start (level 0 to the sink), the GPU's levels and,
// with LN k-means, the optimiser with the host's mirror.
struct GpuLevelsStart {
  std::vector<uint32_t> labels;  // the start's (HC's steps keep their own member lists)
  uint32_t k0 = 0;
  std::optional<PointLevelsGpu> levels;
  std::optional<PointLevelsOptimiser> optimiser;
  PointMultilevelSummary summary;                // level 0's
  ::mlclust::detail::CompensatedSum energy_sum;  // from level 0's energy
};

absl::StatusOr<GpuLevelsStart> StartLevels(GlContext& context, const PointSet& points,
                                           const PointMultilevelOptions& options, LevelSink& sink) {
  const uint32_t d = points.dims;
  MLCLUST_ASSIGN_OR_RETURN(VoxelStartGpuResult voxels,
                           VoxelGridStartGpu(context, points, options.grid, options.cancel));
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "the voxel start"));
  MLCLUST_RETURN_IF_ERROR(CheckSoftwareLoopBudget(context, d, voxels.clusters));
  std::unique_ptr<PointLevelsHost> host = BuildStart(points, voxels, options.cancel);
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "the voxel start's neighbours"));
  GpuLevelsStart made;
  made.k0 = voxels.clusters;
  const uint32_t k0 = made.k0;
  const ::mlclust::detail::PointClusters& start = *host->clusters;
  const double start_energy = start.TotalEnergy();
  MLCLUST_RETURN_IF_ERROR(sink.OnStart(AsClusterIds(voxels.labels), k0, start_energy));
  if (options.inspect_level) options.inspect_level(0, voxels.labels);
  // The upload: counts as uints, each cluster's sums and square sum together.
  std::vector<uint32_t> counts(k0);
  std::vector<double> sums(size_t{k0} * (d + 1));
  for (uint32_t c = 0; c < k0; ++c) {
    counts[c] = static_cast<uint32_t>(start.count(c));
    const std::span<const double> sum = start.sum(c);
    std::copy(sum.begin(), sum.end(), &sums[size_t{c} * (d + 1)]);
    sums[size_t{c} * (d + 1) + d] = start.square(c);
  }
  PointLevelsStart upload;
  upload.dims = d;
  upload.labels = voxels.labels;
  upload.counts = counts;
  upload.sums = sums;
  upload.centroids = start.centroids();
  upload.neighbours = start.neighbour_table();
  MLCLUST_ASSIGN_OR_RETURN(PointLevelsGpu levels, PointLevelsGpu::Create(context, upload));
  made.levels.emplace(std::move(levels));
  // LN k-means inside the levels (points_optimise_gpu.h): the host's clusters become its
  // mirror.
  if (options.optimizer == PointMultilevelOptions::Optimizer::kLnKmeans) {
    MLCLUST_ASSIGN_OR_RETURN(
        PointLevelsOptimiser optimiser,
        PointLevelsOptimiser::Create(context, points, std::move(host), options));
    made.optimiser.emplace(std::move(optimiser));
  }
  made.labels = std::move(voxels.labels);
  made.energy_sum.Reset(start_energy);
  made.summary.levels = 1;
  made.summary.start_clusters = k0;
  made.summary.grid =
      voxels.cells_per_axis.empty()
          ? 0
          : *std::max_element(voxels.cells_per_axis.begin(), voxels.cells_per_axis.end());
  return made;
}

// The caller's inspect_level with the GPU's labels (downloaded).
absl::Status Inspect(const PointMultilevelOptions& options, PointLevelsGpu& levels,
                     uint32_t level) {
  if (!options.inspect_level) return absl::OkStatus();
  MLCLUST_ASSIGN_OR_RETURN(const std::vector<uint32_t> labels, levels.Labels());
  options.inspect_level(level, labels);
  return absl::OkStatus();
}

// HC's and ML's steps (one merge per level) from `started` at `clusters` clusters down to
// options.min_clusters; `table_current`: the optimiser's mirror has the GPU's neighbour
// table (at the start; not after PML's levels).
absl::Status RunSteps(GpuLevelsStart& started, const PointMultilevelOptions& options,
                      LevelSink& sink, bool table_current, uint32_t& clusters) {
  PointLevelsGpu& levels = *started.levels;
  MLCLUST_RETURN_IF_ERROR(levels.StartSteps());
  std::optional<PointLevelsOptimiser>& optimiser = started.optimiser;
  PointMultilevelSummary& summary = started.summary;
  // The clusters' points (the caller's ids) for the triplets: HC's own lists (from the
  // start's labels, or after PML's levels the GPU's), ML's mirror.
  std::vector<std::vector<uint32_t>> members;
  if (!optimiser.has_value()) {
    if (started.labels.empty()) {
      MLCLUST_ASSIGN_OR_RETURN(started.labels, levels.Labels());
    }
    members.resize(started.k0);
    for (size_t i = 0; i < started.labels.size(); ++i) {
      members[started.labels[i]].push_back(static_cast<uint32_t>(i));
    }
  }
  std::vector<uint32_t>().swap(started.labels);
  auto size_of = [&](uint32_t c) -> uint64_t {
    return optimiser.has_value() ? optimiser->size(c) : members[c].size();
  };
  PointLevelGpu level;
  std::vector<uint32_t> touched, rows;
  bool linked = false;
  // ML: the mirror's neighbour table is the GPU's (the start's) until LinkAll changes it
  // all; after each step the refreshed rows come back. After PML's levels it is read once.
  bool read_neighbours = !table_current;
  while (clusters > options.min_clusters) {
    MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, absl::StrCat("level ", summary.levels)));
    uint32_t keep = 0, gone = 0, size = 0;
    MLCLUST_ASSIGN_OR_RETURN(const bool merged, levels.StepMerge(level, keep, gone, size));
    if (!merged) {
      // No ODE left: the CPU's ConnectWhenStuck links the survivors once they are few and
      // recomputes their ODEs.
      if (linked || clusters <= 1 || clusters > kMaxLinked) break;
      MLCLUST_RETURN_IF_ERROR(levels.LinkAll());
      MLCLUST_RETURN_IF_ERROR(levels.StartSteps());
      linked = true;
      read_neighbours = true;
      continue;
    }
    linked = false;
    --clusters;
    // The gone cluster's points (the host's lists, or the mirror's) are the level's
    // triplets and are relabelled on the GPU; the host's sizes must be the GPU's.
    if (size_of(keep) + size_of(gone) != size) {
      return absl::InternalError(absl::StrCat("points on the GPU: the merge of ", gone, " into ",
                                              keep, " gave ", size, " points, the host has ",
                                              size_of(keep), " + ", size_of(gone)));
    }
    if (optimiser.has_value()) {
      optimiser->Members(gone, level.element);
    } else {
      level.element = std::move(members[gone]);
      std::vector<uint32_t>().swap(members[gone]);
      std::sort(level.element.begin(), level.element.end());
      members[keep].insert(members[keep].end(), level.element.begin(), level.element.end());
    }
    level.to_cluster.assign(level.element.size(), keep);
    level.from_cluster.assign(level.element.size(), gone);
    MLCLUST_RETURN_IF_ERROR(levels.Update({}, {}, {}, level.element, level.to_cluster));
    if (optimiser.has_value()) {
      // LN k-means around the merge (the CPU's rounds) and the level's report.
      MLCLUST_RETURN_IF_ERROR(
          optimiser->Level(levels, level, sink, summary.levels, clusters, read_neighbours));
      read_neighbours = false;
      const std::span<const uint32_t> changed = optimiser->touched();
      touched.assign(changed.begin(), changed.end());
      summary.moves = optimiser->moves();
    } else {
      touched = {keep, gone};
      started.energy_sum.Add(level.energy_change);
      MLCLUST_RETURN_IF_ERROR(
          SendGpuLevel(level, summary.levels, clusters, started.energy_sum.value(), sink));
      summary.moves += level.element.size();
    }
    MLCLUST_RETURN_IF_ERROR(
        levels.StepRefresh(keep, gone, touched, optimiser.has_value() ? &rows : nullptr));
    if (optimiser.has_value()) MLCLUST_RETURN_IF_ERROR(optimiser->SetNeighbourRows(rows));
    MLCLUST_RETURN_IF_ERROR(Inspect(options, levels, summary.levels));
    ++summary.levels;
  }
  return absl::OkStatus();
}

}  // namespace

absl::StatusOr<PointMultilevelSummary> RunPointParallelMultilevelGpu(
    GlContext& context, const PointSet& points, const PointMultilevelOptions& options,
    LevelSink& sink) {
  MLCLUST_RETURN_IF_ERROR(::mlclust::detail::CheckPointLevelsArguments(points, options));
  const std::string unsupported = PointsPmlGpuUnsupported(options);
  if (!unsupported.empty()) {
    return absl::UnimplementedError(absl::StrCat("PML for points on the GPU: ", unsupported));
  }
  MLCLUST_ASSIGN_OR_RETURN(GpuLevelsStart started, StartLevels(context, points, options, sink));
  std::vector<uint32_t>().swap(started.labels);  // stale after the first level
  PointLevelsGpu& levels = *started.levels;
  std::optional<PointLevelsOptimiser>& optimiser = started.optimiser;
  PointMultilevelSummary& summary = started.summary;
  ::mlclust::detail::CompensatedSum& energy = started.energy_sum;
  uint32_t clusters = started.k0;
  PointLevelGpu level;
  bool linked = false, stuck = false;
  // PML's levels while more than pml_until clusters are left, then ML's (or HC's) steps.
  while (clusters > std::max(options.min_clusters, options.pml_until)) {
    MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, absl::StrCat("level ", summary.levels)));
    MLCLUST_ASSIGN_OR_RETURN(
        const bool merged,
        optimiser.has_value()
            ? levels.MergeLevel(options.pml_pairs, clusters, options.min_clusters, level)
            : levels.Level(options.pml_pairs, clusters, options.min_clusters, level));
    if (!merged) {
      // No pair left: the CPU's ConnectWhenStuck links the survivors once they are few.
      stuck = linked || clusters <= 1 || clusters > kMaxLinked;
      if (stuck) break;
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
    MLCLUST_RETURN_IF_ERROR(Inspect(options, levels, summary.levels));
    ++summary.levels;
  }
  if (!stuck && clusters > options.min_clusters) {
    MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, absl::StrCat("level ", summary.levels)));
    MLCLUST_RETURN_IF_ERROR(RunSteps(started, options, sink, /*table_current=*/false, clusters));
  }
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, absl::StrCat("level ", summary.levels)));
  summary.final_clusters = clusters;
  return summary;
}

absl::StatusOr<PointMultilevelSummary> RunPointHierarchyGpu(GlContext& context,
                                                            const PointSet& points,
                                                            const PointMultilevelOptions& options,
                                                            LevelSink& sink) {
  MLCLUST_RETURN_IF_ERROR(::mlclust::detail::CheckPointLevelsArguments(points, options));
  if (options.parallel) {
    return absl::UnimplementedError(
        "HC and ML for points on the GPU: one merge per level (PML is "
        "RunPointParallelMultilevelGpu)");
  }
  const std::string unsupported = PointsStartGpuUnsupported(options);
  if (!unsupported.empty()) {
    return absl::UnimplementedError(absl::StrCat("HC and ML for points on the GPU: ", unsupported));
  }
  MLCLUST_ASSIGN_OR_RETURN(GpuLevelsStart started, StartLevels(context, points, options, sink));
  uint32_t clusters = started.k0;
  MLCLUST_RETURN_IF_ERROR(RunSteps(started, options, sink, /*table_current=*/true, clusters));
  PointMultilevelSummary& summary = started.summary;
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, absl::StrCat("level ", summary.levels)));
  summary.final_clusters = clusters;
  return summary;
}

}  // namespace mlclust::gpu
