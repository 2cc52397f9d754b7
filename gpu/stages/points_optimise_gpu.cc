#include "gpu/stages/points_optimise_gpu.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"
#include "core/base/status_macros.h"
#include "core/energy/variance_energy.h"

namespace mlclust::gpu {
namespace {

constexpr uint32_t kNone = 0xFFFFFFFFu;

}  // namespace

absl::StatusOr<PointLevelsOptimiser> PointLevelsOptimiser::Create(GlContext& context,
                                                                  const PointSet& points,
                                                                  PointOptimiserStart start,
                                                                  uint32_t rounds,
                                                                  const std::atomic<bool>* cancel) {
  const uint64_t k = start.counts.size();
  const uint32_t d = points.dims;
  if (start.labels.size() != points.num_points() || start.sums.size() != k * (d + 1) ||
      start.centroids.size() != k * d || start.origin.size() != d) {
    return absl::InvalidArgumentError(absl::StrCat(
        "LN k-means in the GPU's point levels: a start of ", start.labels.size(), " labels and ", k,
        " clusters does not fit ", points.num_points(), " points of ", d, " dimensions"));
  }
  MLCLUST_ASSIGN_OR_RETURN(LnKmeansKernel kernel,
                           LnKmeansKernel::Create(context, points, start.origin, 0));
  return PointLevelsOptimiser(points, std::move(start), rounds, cancel, std::move(kernel));
}

PointLevelsOptimiser::PointLevelsOptimiser(const PointSet& points, PointOptimiserStart start,
                                           uint32_t rounds, const std::atomic<bool>* cancel,
                                           LnKmeansKernel kernel)
    : points_(&points),
      d_(points.dims),
      state_(std::move(start)),
      rounds_(rounds),
      cancel_(cancel),
      kernel_(std::move(kernel)),
      recorder_(points.num_points(), static_cast<uint32_t>(state_.counts.size())) {
  const size_t m = state_.labels.size();
  const size_t k = state_.counts.size();
  // Member lists in point order within each cluster: the order of the CPU's PointSpace
  // (points sorted by starting cell, stably).
  members_.resize(k);
  for (uint32_t c = 0; c < k; ++c) members_[c].reserve(state_.counts[c]);
  position_.resize(m);
  for (size_t i = 0; i < m; ++i) {
    std::vector<uint32_t>& list = members_[state_.labels[i]];
    position_[i] = static_cast<uint32_t>(list.size());
    list.push_back(static_cast<uint32_t>(i));
  }
  mark_.assign(k, 0);
  stamp_.assign(m, 0);
  threshold_.assign(m, 0.0);
  drift_epoch_.assign(k, 0);
  region_epoch_.assign(k, 0);
  drift_.assign(k, 0.0);
  recorder_.Reset(state_.energy);
}

double PointLevelsOptimiser::Energy(uint32_t c) const {
  const double* sum = &state_.sums[size_t{c} * (d_ + 1)];
  return EnergyOfSums(static_cast<double>(state_.counts[c]), {sum, d_}, sum[d_]);
}

void PointLevelsOptimiser::UpdateCentroid(uint32_t c) {
  const double n = static_cast<double>(state_.counts[c]);
  for (uint32_t j = 0; j < d_; ++j) {
    state_.centroids[size_t{c} * d_ + j] = n > 0 ? state_.sums[size_t{c} * (d_ + 1) + j] / n : 0.0;
  }
}

void PointLevelsOptimiser::Add(uint32_t c, uint32_t i, int sign) {
  const float* x = &points_->values[size_t{i} * d_];
  double* sum = &state_.sums[size_t{c} * (d_ + 1)];
  double s2 = 0;
  for (uint32_t j = 0; j < d_; ++j) {
    const double v = x[j] - state_.origin[j];
    sum[j] += sign * v;
    s2 += v * v;
  }
  sum[d_] += sign * s2;
  state_.counts[c] = static_cast<uint32_t>(static_cast<int64_t>(state_.counts[c]) + sign);
}

// The level's merges from the GPU's triplets (point, kept cluster, gone cluster): per
// pair, in the order of its first point, the CPU's Merge (touch both, record the gone
// one's points) with points_merge.glsl's sums in its operation order, so the mirror keeps
// the GPU's values bit for bit.
absl::Status PointLevelsOptimiser::ApplyMerges(const PointLevelGpu& merged) {
  merged_.clear();
  const auto energy_of = [&](uint32_t c) { return Energy(c); };
  for (size_t t = 0; t < merged.element.size(); ++t) {
    const uint32_t i = merged.element[t], keep = merged.to_cluster[t],
                   gone = merged.from_cluster[t];
    const bool done = gone < mark_.size() && state_.counts[gone] == 0;  // merged already
    if (i >= state_.labels.size() || keep >= mark_.size() || gone >= mark_.size() ||
        state_.labels[i] != (done ? keep : gone)) {
      return absl::InternalError(
          absl::StrCat("LN k-means in the GPU's point levels: the GPU's triplet (", i, ", ", keep,
                       ", ", gone, ") does not match the host's labels"));
    }
    if (done) continue;
    recorder_.Touch(keep, energy_of);
    recorder_.Touch(gone, energy_of);
    const size_t kept = size_t{keep} * (d_ + 1), away = size_t{gone} * (d_ + 1);
    state_.sums[kept + d_] = state_.sums[kept + d_] + state_.sums[away + d_];
    state_.sums[away + d_] = 0.0;
    state_.counts[keep] += state_.counts[gone];
    state_.counts[gone] = 0;
    for (uint32_t j = 0; j < d_; ++j) {
      state_.sums[kept + j] = state_.sums[kept + j] + state_.sums[away + j];
      state_.sums[away + j] = 0.0;
    }
    UpdateCentroid(keep);
    for (const uint32_t p : members_[gone]) {
      recorder_.RecordMove(p, gone);
      state_.labels[p] = keep;
      position_[p] = static_cast<uint32_t>(members_[keep].size());
      members_[keep].push_back(p);
    }
    std::vector<uint32_t>().swap(members_[gone]);
    merged_.push_back(keep);
  }
  return absl::OkStatus();
}

void PointLevelsOptimiser::ApplyMoves() {
  changed_.clear();
  moved_.clear();
  old_centroids_.clear();
  const auto energy_of = [&](uint32_t c) { return Energy(c); };
  for (size_t r = 0; r < check_.size(); ++r) {
    const uint32_t to = target_[r];
    if (to == kNone) continue;
    const uint32_t i = check_[r];
    const uint32_t from = state_.labels[i];
    if (state_.counts[from] <= 1) continue;  // a cluster's last point stays
    for (const uint32_t c : {from, to}) {
      if (!mark_[c]) {
        mark_[c] = 1;
        changed_.push_back(c);
        const double* centroid = &state_.centroids[size_t{c} * d_];
        old_centroids_.insert(old_centroids_.end(), centroid, centroid + d_);
        if (drift_epoch_[c] != epoch_) {
          drift_epoch_[c] = epoch_;
          drift_[c] = 0;
        }
      }
    }
    recorder_.Touch(from, energy_of);
    recorder_.Touch(to, energy_of);
    recorder_.RecordMove(i, from);
    stamp_[i] = 0;  // its candidates are another cluster's now: check it again
    Add(from, i, -1);
    state_.labels[i] = to;
    Add(to, i, +1);
    std::vector<uint32_t>& list = members_[from];
    const uint32_t at = position_[i];
    list[at] = list.back();
    position_[list[at]] = at;
    list.pop_back();
    position_[i] = static_cast<uint32_t>(members_[to].size());
    members_[to].push_back(i);
    moved_.push_back(i);
  }
  for (size_t n = 0; n < changed_.size(); ++n) {
    const uint32_t c = changed_[n];
    mark_[c] = 0;
    UpdateCentroid(c);
    double squared = 0;
    for (uint32_t j = 0; j < d_; ++j) {
      const double diff = state_.centroids[size_t{c} * d_ + j] - old_centroids_[n * d_ + j];
      squared += diff * diff;
    }
    drift_[c] += std::sqrt(squared) * (1 + 1e-12);
  }
}

double PointLevelsOptimiser::NeighbourhoodDrift(uint32_t c) const {
  double largest = 0;
  const size_t slots = 2 * size_t{d_};
  for (size_t s = 0; s < slots; ++s) {
    const uint32_t n = table_[c * slots + s];
    if (n == kNone) continue;
    largest = std::max(largest, Drift(n));
    for (size_t t = 0; t < slots; ++t) {
      const uint32_t nn = table_[n * slots + t];
      if (nn != kNone && nn != c) largest = std::max(largest, Drift(nn));
    }
  }
  return largest;
}

void PointLevelsOptimiser::SelectForCheck(std::span<const uint32_t> region) {
  check_.clear();
  for (const uint32_t c : region) {
    const double drift = Drift(c) + NeighbourhoodDrift(c);
    const bool all = region_epoch_[c] != epoch_;
    region_epoch_[c] = epoch_;
    for (const uint32_t i : members_[c]) {
      if (all || stamp_[i] != epoch_ || drift > threshold_[i]) check_.push_back(i);
    }
  }
}

absl::Status PointLevelsOptimiser::WriteBack(PointLevelsGpu& levels) {
  const size_t width = 2 * size_t{d_} + 1;
  std::vector<uint32_t> counts(changed_.size()), labels(moved_.size());
  std::vector<double> values(changed_.size() * width);
  for (size_t r = 0; r < changed_.size(); ++r) {
    const uint32_t c = changed_[r];
    counts[r] = state_.counts[c];
    std::copy_n(&state_.sums[size_t{c} * (d_ + 1)], d_ + 1, &values[r * width]);
    std::copy_n(&state_.centroids[size_t{c} * d_], d_, &values[r * width + d_ + 1]);
  }
  for (size_t r = 0; r < moved_.size(); ++r) labels[r] = state_.labels[moved_[r]];
  return levels.Update(changed_, counts, values, moved_, labels);
}

absl::Status PointLevelsOptimiser::Level(PointLevelsGpu& levels, const PointLevelGpu& merged,
                                         LevelSink& sink, uint32_t index, uint32_t clusters) {
  MLCLUST_RETURN_IF_ERROR(ApplyMerges(merged));
  // Round 0 (PointSpace::Optimise): every point of the merged clusters gets the full check;
  // a point of a cluster next to a merged one (the neighbour table before the level's
  // refresh) can only gain by moving to a merged cluster, so it is compared with the merged
  // clusters that list its cluster, and with nothing else.
  std::vector<uint32_t> region;
  for (const uint32_t c : merged_) {
    if (!mark_[c] && state_.counts[c] > 0) {
      mark_[c] = 1;
      region.push_back(c);
    }
  }
  std::vector<std::pair<uint32_t, uint32_t>> next_to;  // (cluster, merged cluster)
  if (rounds_ > 0 && !region.empty()) {
    MLCLUST_ASSIGN_OR_RETURN(table_, levels.Neighbours());
    for (const uint32_t c : region) {
      const uint32_t* row = &table_[size_t{c} * 2 * d_];
      for (uint32_t s = 0; s < 2 * d_; ++s) {
        const uint32_t n = row[s];
        if (n != kNone && !mark_[n] && state_.counts[n] > 0) next_to.emplace_back(n, c);
      }
    }
  }
  for (const uint32_t c : region) mark_[c] = 0;
  std::sort(next_to.begin(), next_to.end());
  next_to.erase(std::unique(next_to.begin(), next_to.end()), next_to.end());
  ++epoch_;
  for (uint32_t round = 0; round < rounds_ && !region.empty(); ++round) {
    MLCLUST_RETURN_IF_ERROR(
        CheckCancelled(cancel_, absl::StrCat("LN k-means round ", round, " of level ", index)));
    LnKmeansOwnCandidates own;
    std::vector<uint32_t> ranges, candidates;
    if (round == 0) {
      check_.clear();
      for (const uint32_t c : region) {
        region_epoch_[c] = epoch_;
        check_.insert(check_.end(), members_[c].begin(), members_[c].end());
      }
      own.full = check_.size();
      for (const auto& [n, c] : next_to) candidates.push_back(c);
      for (size_t g = 0; g < next_to.size();) {
        size_t end = g;
        while (end < next_to.size() && next_to[end].first == next_to[g].first) ++end;
        for (const uint32_t i : members_[next_to[g].first]) {
          check_.push_back(i);
          ranges.push_back(static_cast<uint32_t>(g));
          ranges.push_back(static_cast<uint32_t>(end));
        }
        g = end;
      }
      own.ranges = ranges;
      own.candidates = candidates;
    } else {
      SelectForCheck(region);
      own.full = check_.size();
    }
    target_.resize(check_.size());
    margin_.resize(check_.size());
    MLCLUST_RETURN_IF_ERROR(
        kernel_.AssignResident(levels.Resident(), check_, target_, margin_, own));
    for (size_t r = 0; r < own.full; ++r) {
      const uint32_t i = check_[r];
      stamp_[i] = epoch_;
      threshold_[i] = margin_[r] + Drift(state_.labels[i]);
    }
    ApplyMoves();
    if (changed_.empty()) break;
    MLCLUST_RETURN_IF_ERROR(WriteBack(levels));
    region = changed_;
  }
  recorder_.Squash([&](uint32_t c) { return Energy(c); },
                   [&](uint32_t i) { return state_.labels[i]; }, [](uint32_t i) { return i; });
  return recorder_.Emit(sink, index, clusters);
}

}  // namespace mlclust::gpu
