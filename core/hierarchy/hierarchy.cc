#include "core/hierarchy/hierarchy.h"

#include <algorithm>

#include "absl/strings/str_cat.h"
#include "core/base/status_macros.h"

namespace mlclust {

absl::Status HierarchyLog::OnStart(std::span<const ClusterId> labels, uint32_t cluster_count,
                                   double energy) {
  if (num_levels() != 0) return absl::FailedPreconditionError("level 0 was already set");
  start_labels_.assign(labels.begin(), labels.end());
  cluster_count_ = {cluster_count};
  energy_ = {energy};
  level_end_ = {0};
  seen_in_level_.assign(labels.size(), 0);
  stamp_ = 0;
  return absl::OkStatus();
}

absl::Status HierarchyLog::OnLevel(const LevelMoves& level) {
  if (num_levels() == 0) return absl::FailedPreconditionError("a level before level 0");
  const size_t count = level.element.size();
  if (level.to_cluster.size() != count || level.from_cluster.size() != count) {
    return absl::InvalidArgumentError(absl::StrCat(
        "level ", num_levels(), ": triplet arrays differ in length (", count, " elements, ",
        level.to_cluster.size(), " new clusters, ", level.from_cluster.size(), " old clusters)"));
  }
  // Stamp elements with a per-call number to find repeats without clearing the scratch
  // (a per-call stamp, not the level number, so that a refused level leaves no trace).
  if (++stamp_ == 0) {
    std::fill(seen_in_level_.begin(), seen_in_level_.end(), 0);
    stamp_ = 1;
  }
  const uint32_t stamp = stamp_;
  for (size_t i = 0; i < count; ++i) {
    const uint32_t e = level.element[i];
    if (e >= start_labels_.size()) {
      return absl::InvalidArgumentError(absl::StrCat("level ", num_levels(), ": element ", e,
                                                     " out of range (", start_labels_.size(),
                                                     " elements)"));
    }
    if (seen_in_level_[e] == stamp) {
      return absl::InvalidArgumentError(
          absl::StrCat("level ", num_levels(), ": element ", e, " appears twice"));
    }
    seen_in_level_[e] = stamp;
  }
  element_.insert(element_.end(), level.element.begin(), level.element.end());
  to_cluster_.insert(to_cluster_.end(), level.to_cluster.begin(), level.to_cluster.end());
  from_cluster_.insert(from_cluster_.end(), level.from_cluster.begin(), level.from_cluster.end());
  level_end_.push_back(element_.size());
  cluster_count_.push_back(level.cluster_count);
  energy_.push_back(level.energy);
  return absl::OkStatus();
}

LevelMoves HierarchyLog::level(size_t level) const {
  const size_t begin = level_end_[level - 1];
  const size_t count = level_end_[level] - begin;
  LevelMoves moves;
  moves.cluster_count = cluster_count_[level];
  moves.energy = energy_[level];
  moves.element = {element_.data() + begin, count};
  moves.to_cluster = {to_cluster_.data() + begin, count};
  moves.from_cluster = {from_cluster_.data() + begin, count};
  return moves;
}

absl::Status HierarchyLog::StepLabels(std::vector<ClusterId>& labels, size_t from_level,
                                      size_t to_level) const {
  if (from_level >= num_levels() || to_level >= num_levels()) {
    return absl::OutOfRangeError(absl::StrCat("level ", std::max(from_level, to_level),
                                              " is past the last level (", num_levels(),
                                              " levels)"));
  }
  if (labels.size() != start_labels_.size()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "labels hold ", labels.size(), " elements, the hierarchy ", start_labels_.size()));
  }
  auto apply = [&](size_t l, bool forward) -> absl::Status {
    const size_t begin = level_end_[l - 1], end = level_end_[l];
    for (size_t i = begin; i < end; ++i) {
      const uint32_t expected = forward ? from_cluster_[i] : to_cluster_[i];
      ClusterId& label = labels[element_[i]];
      if (label.value() != expected) {
        return absl::DataLossError(absl::StrCat("level ", l, ": element ", element_[i],
                                                " is in cluster ", label.value(), ", expected ",
                                                expected));
      }
      label = ClusterId(forward ? to_cluster_[i] : from_cluster_[i]);
    }
    return absl::OkStatus();
  };
  for (size_t l = from_level + 1; l <= to_level; ++l) {
    MLCLUST_RETURN_IF_ERROR(apply(l, true));
  }
  for (size_t l = from_level; l > to_level; --l) {
    MLCLUST_RETURN_IF_ERROR(apply(l, false));
  }
  return absl::OkStatus();
}

absl::StatusOr<std::vector<ClusterId>> HierarchyLog::LabelsAt(size_t level) const {
  std::vector<ClusterId> labels = start_labels_;
  MLCLUST_RETURN_IF_ERROR(StepLabels(labels, 0, level));
  return labels;
}

std::optional<size_t> HierarchyLog::FirstLevelWithAtMost(uint32_t k) const {
  for (size_t l = 0; l < num_levels(); ++l) {
    if (cluster_count_[l] <= k) return l;
  }
  return std::nullopt;
}

std::optional<size_t> HierarchyLog::LastLevelWith(uint32_t k) const {
  for (size_t l = num_levels(); l-- > 0;) {
    if (cluster_count_[l] == k) return l;
  }
  return std::nullopt;
}

}  // namespace mlclust
