#include "gpu/stages/points_optimise_gpu.h"

#include <algorithm>
#include <tuple>
#include <utility>

#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"
#include "core/base/status_macros.h"
#include "core/cluster/detail/ln_kmeans_stages.h"

namespace mlclust::gpu {
namespace {

using ::mlclust::detail::PointClusters;
using ::mlclust::detail::PointOptimiseRounds;

constexpr uint32_t kNone = 0xFFFFFFFFu;

}  // namespace

std::unique_ptr<PointLevelsHost> MakePointLevelsHost(const PointSet& points,
                                                     std::span<const uint32_t> labels,
                                                     uint32_t clusters) {
  const size_t m = points.num_points();
  const uint32_t d = points.dims;
  auto host = std::make_unique<PointLevelsHost>();
  std::vector<uint32_t> first(size_t{clusters} + 1, 0), sorted_labels(m);
  for (const uint32_t c : labels) ++first[c + 1];
  for (uint32_t c = 0; c < clusters; ++c) first[c + 1] += first[c];
  host->original.resize(m);
  host->sorted_of.resize(m);
  host->sorted.dims = d;
  host->sorted.values.resize(points.values.size());
  for (size_t i = 0; i < m; ++i) {
    const uint32_t at = first[labels[i]]++;
    host->original[at] = static_cast<uint32_t>(i);
    host->sorted_of[i] = at;
    sorted_labels[at] = labels[i];
    std::copy_n(&points.values[i * d], d, &host->sorted.values[size_t{at} * d]);
  }
  host->clusters = std::make_unique<PointClusters>(host->sorted, sorted_labels, clusters);
  return host;
}

struct PointLevelsOptimiser::Mirror {
  const PointMultilevelOptions* options = nullptr;
  std::unique_ptr<PointLevelsHost> host;
  LevelRecorder recorder{0, 0};
  std::unique_ptr<PointOptimiseRounds> rounds;
  // Scratch: the level's pairs (cost, kept, gone) and merged clusters, a round's check list
  // (sorted's points, then the caller's), own candidates in groups, targets and margins, the
  // triplets per gone cluster.
  std::vector<std::tuple<double, uint32_t, uint32_t>> pairs;
  std::vector<uint32_t> merged, check, check_gpu, groups, starts, candidates, target, tally;
  std::vector<uint32_t> touched;  // the last level's recorder.affected()
  std::vector<double> margin;
};

absl::StatusOr<PointLevelsOptimiser> PointLevelsOptimiser::Create(
    GlContext& context, const PointSet& points, std::unique_ptr<PointLevelsHost> host,
    const PointMultilevelOptions& options) {
  const size_t m = points.num_points();
  const uint32_t d = points.dims;
  if (host == nullptr || host->clusters == nullptr || host->sorted.dims != d ||
      host->original.size() != m) {
    return absl::InvalidArgumentError(
        absl::StrCat("LN k-means in the GPU's point levels: a start that does not fit ", m,
                     " points of ", d, " dimensions"));
  }
  const uint32_t clusters = host->clusters->capacity();
  auto mirror = std::make_unique<Mirror>();
  mirror->options = &options;
  mirror->host = std::move(host);
  PointClusters& mirrored = *mirror->host->clusters;
  mirror->recorder = LevelRecorder(m, clusters);
  mirror->recorder.Reset(mirrored.TotalEnergy());
  mirror->rounds = std::make_unique<PointOptimiseRounds>(
      mirrored, mirror->recorder, options.optimise_rounds, options.bounded_drift);
  mirror->tally.assign(clusters, 0);
  // Round 0 compares the points next to the merged clusters with at most 2d merged
  // clusters that list their cluster each: fewer than 2d k candidates in all.
  MLCLUST_ASSIGN_OR_RETURN(
      LnKmeansKernel kernel,
      LnKmeansKernel::Create(context, points, mirrored.origin(), 0, 2 * uint64_t{d} * clusters));
  return PointLevelsOptimiser(std::move(mirror), std::move(kernel));
}

PointLevelsOptimiser::PointLevelsOptimiser(std::unique_ptr<Mirror> mirror, LnKmeansKernel kernel)
    : mirror_(std::move(mirror)), kernel_(std::move(kernel)) {}
PointLevelsOptimiser::PointLevelsOptimiser(PointLevelsOptimiser&&) noexcept = default;
PointLevelsOptimiser& PointLevelsOptimiser::operator=(PointLevelsOptimiser&&) noexcept = default;
PointLevelsOptimiser::~PointLevelsOptimiser() = default;

uint64_t PointLevelsOptimiser::moves() const { return mirror_->recorder.moves(); }

std::span<const uint32_t> PointLevelsOptimiser::touched() const { return mirror_->touched; }

// The level's merges from the GPU's triplets (point, kept cluster, gone cluster): every
// triplet must name a point of its gone cluster, and every point of a gone cluster must
// have one. The pairs merge in the CPU engine's order (merge cost, then pair).
absl::Status PointLevelsOptimiser::ApplyMerges(const PointLevelGpu& merged) {
  Mirror& s = *mirror_;
  PointClusters& clusters = *s.host->clusters;
  const uint32_t k = clusters.capacity();
  s.pairs.clear();
  for (size_t t = 0; t < merged.element.size(); ++t) {
    const uint32_t i = merged.element[t], keep = merged.to_cluster[t],
                   gone = merged.from_cluster[t];
    if (i >= s.host->sorted_of.size() || keep >= k || gone >= k || keep == gone ||
        clusters.label(s.host->sorted_of[i]) != gone || clusters.count(keep) == 0) {
      return absl::InternalError(
          absl::StrCat("LN k-means in the GPU's point levels: the GPU's triplet (", i, ", ", keep,
                       ", ", gone, ") does not match the host's labels"));
    }
    if (s.tally[gone]++ == 0) {
      const uint32_t a = std::min(keep, gone), b = std::max(keep, gone);
      s.pairs.emplace_back(clusters.MergeCost(a, b), keep, gone);
    }
  }
  absl::Status status = absl::OkStatus();
  for (const auto& [cost, keep, gone] : s.pairs) {
    if (s.tally[gone] != clusters.count(gone) && status.ok()) {
      status = absl::InternalError(
          absl::StrCat("LN k-means in the GPU's point levels: the GPU moved ", s.tally[gone],
                       " points of cluster ", gone, ", which has ", clusters.count(gone)));
    }
    s.tally[gone] = 0;
  }
  MLCLUST_RETURN_IF_ERROR(status);
  std::sort(s.pairs.begin(), s.pairs.end(), [](const auto& x, const auto& y) {
    const auto& [cx, kx, gx] = x;
    const auto& [cy, ky, gy] = y;
    if (cx != cy) return cx < cy;
    return std::minmax(kx, gx) < std::minmax(ky, gy);
  });
  s.merged.clear();
  for (const auto& [cost, keep, gone] : s.pairs) {
    s.rounds->Merge(keep, gone);
    s.merged.push_back(keep);
  }
  return absl::OkStatus();
}

absl::Status PointLevelsOptimiser::Check(PointLevelsGpu& levels,
                                         std::span<const PointOptimiseRounds::Slice> slices,
                                         std::span<const PointOptimiseRounds::NextTo> next_to,
                                         std::vector<PointOptimiseRounds::Move>& moves) {
  Mirror& s = *mirror_;
  PointOptimiseRounds& rounds = *s.rounds;
  // The region's slices come first (PointOptimiseRounds::Run): their points get the full
  // check; round 0's next-to slices after them, with their merged clusters.
  // A next-to point's group: its cluster's run of next_to (the merged clusters that list
  // it); the groups' starts in next_to, whose merged clusters are the candidates.
  s.check.clear();
  s.groups.clear();
  s.starts.clear();
  s.candidates.clear();
  size_t full = 0;
  std::pair<uint32_t, double> drift_of{kNone, 0.0};
  for (const PointOptimiseRounds::Slice& slice : slices) {
    if (slice.compare_end > slice.compare_begin) {
      if (s.starts.empty()) {
        for (size_t g = 0; g < next_to.size(); ++g) {
          if (g == 0 || next_to[g].first != next_to[g - 1].first) {
            s.starts.push_back(static_cast<uint32_t>(g));
          }
        }
        s.starts.push_back(static_cast<uint32_t>(next_to.size()));
        for (const auto& pair : next_to) s.candidates.push_back(pair.second);
      }
      const auto group = static_cast<uint32_t>(
          std::lower_bound(s.starts.begin(), s.starts.end(), slice.compare_begin) -
          s.starts.begin());
      const std::span<const uint32_t> list = rounds.members(slice.cluster);
      for (size_t at = slice.begin; at < slice.end; ++at) {
        s.check.push_back(list[at]);
        s.groups.push_back(group);
      }
      continue;
    }
    const size_t at = s.check.size();
    s.check.resize(at + (slice.end - slice.begin));
    s.check.resize(at + rounds.Scan(slice, s.check.data() + at, drift_of));
    full = s.check.size();
  }
  s.check_gpu.resize(s.check.size());
  for (size_t r = 0; r < s.check.size(); ++r) s.check_gpu[r] = s.host->original[s.check[r]];
  s.target.resize(s.check.size());
  s.margin.resize(s.check.size());
  LnKmeansOwnCandidates own;
  own.full = full;
  own.groups = s.groups;
  own.starts = s.starts;
  own.candidates = s.candidates;
  MLCLUST_RETURN_IF_ERROR(
      kernel_.AssignResident(levels.Resident(), s.check_gpu, s.target, s.margin, own));
  moves.clear();
  for (size_t r = 0; r < s.check.size(); ++r) {
    if (r < full) rounds.Stamp(s.check[r], s.margin[r]);
    if (s.target[r] != kNone) moves.emplace_back(s.check[r], s.target[r]);
  }
  return absl::OkStatus();
}

absl::Status PointLevelsOptimiser::WriteBack(PointLevelsGpu& levels,
                                             std::span<const uint32_t> changed,
                                             std::span<const PointOptimiseRounds::Move> moved) {
  const PointClusters& clusters = *mirror_->host->clusters;
  const uint32_t d = clusters.dims();
  const size_t width = 2 * size_t{d} + 1;
  std::vector<uint32_t> counts(changed.size()), points(moved.size()), labels(moved.size());
  std::vector<double> values(changed.size() * width);
  for (size_t r = 0; r < changed.size(); ++r) {
    const uint32_t c = changed[r];
    counts[r] = static_cast<uint32_t>(clusters.count(c));
    const std::span<const double> sum = clusters.sum(c), centroid = clusters.centroid(c);
    std::copy(sum.begin(), sum.end(), &values[r * width]);
    values[r * width + d] = clusters.square(c);
    std::copy(centroid.begin(), centroid.end(), &values[r * width + d + 1]);
  }
  for (size_t r = 0; r < moved.size(); ++r) {
    points[r] = mirror_->host->original[moved[r].first];
    labels[r] = clusters.label(moved[r].first);
  }
  return levels.Update(changed, counts, values, points, labels);
}

uint64_t PointLevelsOptimiser::size(uint32_t c) const { return mirror_->host->clusters->count(c); }

void PointLevelsOptimiser::Members(uint32_t c, std::vector<uint32_t>& out) const {
  out.clear();
  for (const uint32_t i : mirror_->rounds->members(c)) out.push_back(mirror_->host->original[i]);
  std::sort(out.begin(), out.end());
}

absl::Status PointLevelsOptimiser::SetNeighbourRows(std::span<const uint32_t> rows) {
  PointClusters& clusters = *mirror_->host->clusters;
  const size_t slots = 2 * size_t{clusters.dims()};
  const size_t ids = rows.size() / (slots + 1);
  if (ids * (slots + 1) != rows.size()) {
    return absl::InternalError("LN k-means in the GPU's point levels: rows that do not fit");
  }
  for (size_t r = 0; r < ids; ++r) {
    if (rows[r] >= clusters.capacity()) {
      return absl::InternalError("LN k-means in the GPU's point levels: a row out of range");
    }
    const std::span<const uint32_t> row = rows.subspan(ids + r * slots, slots);
    std::copy(row.begin(), row.end(), clusters.neighbours(rows[r]).begin());
  }
  return absl::OkStatus();
}

absl::Status PointLevelsOptimiser::Level(PointLevelsGpu& levels, const PointLevelGpu& merged,
                                         LevelSink& sink, uint32_t index, uint32_t clusters,
                                         bool read_neighbours) {
  Mirror& s = *mirror_;
  MLCLUST_RETURN_IF_ERROR(ApplyMerges(merged));
  if (!s.merged.empty() && read_neighbours) {
    // The neighbour table before the level's refresh, as the CPU's rounds see it.
    MLCLUST_ASSIGN_OR_RETURN(const std::vector<uint32_t> table, levels.Neighbours());
    std::copy(table.begin(), table.end(), s.host->clusters->neighbour_table().begin());
  }
  MLCLUST_RETURN_IF_ERROR(s.rounds->Run(
      s.merged, s.options->cancel,
      [&](std::span<const PointOptimiseRounds::Slice> slices,
          std::span<const PointOptimiseRounds::NextTo> next_to,
          std::vector<PointOptimiseRounds::Move>& moves) {
        return Check(levels, slices, next_to, moves);
      },
      [&](std::span<const uint32_t> changed, std::span<const PointOptimiseRounds::Move> moved) {
        return WriteBack(levels, changed, moved);
      }));
  MLCLUST_RETURN_IF_ERROR(
      CheckCancelled(s.options->cancel, absl::StrCat("LN k-means of level ", index)));
  const PointClusters& clusters_now = *s.host->clusters;
  s.recorder.Squash([&](uint32_t c) { return clusters_now.Energy(c); },
                    [&](uint32_t i) { return clusters_now.label(i); },
                    [&](uint32_t i) { return s.host->original[i]; });
  const std::span<const uint32_t> affected = s.recorder.affected();
  s.touched.assign(affected.begin(), affected.end());
  return s.recorder.Emit(sink, index, clusters);
}

}  // namespace mlclust::gpu
