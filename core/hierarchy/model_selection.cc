#include "core/hierarchy/model_selection.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>

#include "absl/strings/str_cat.h"

namespace mlclust {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

double SizeLogSize(uint64_t size) {
  if (size == 0) return 0;
  const double r = static_cast<double>(size);
  return r * std::log(r);
}

}  // namespace

double SphericalGaussianBicFromSizeTerm(double size_term, uint64_t clusters, double sse,
                                        uint64_t num_points, uint32_t dims) {
  assert(clusters >= 1 && clusters <= num_points && dims >= 1);
  // Degenerate levels (see the header): no variance can be estimated.
  if (clusters >= num_points || !(sse > 0)) return -kInfinity;
  const double r = static_cast<double>(num_points);
  const double k = static_cast<double>(clusters);
  const double m = static_cast<double>(dims);
  const double variance = sse / (m * (r - k));
  const double log_likelihood = size_term - r * std::log(r) -
                                0.5 * r * m * std::log(2 * std::numbers::pi * variance) -
                                0.5 * m * (r - k);
  const double parameters = (k - 1) + m * k + 1;
  return log_likelihood - 0.5 * parameters * std::log(r);
}

double SphericalGaussianBic(std::span<const uint64_t> cluster_sizes, double sse,
                            uint64_t num_points, uint32_t dims) {
  double size_term = 0;
  uint64_t clusters = 0;
  uint64_t total = 0;
  for (uint64_t size : cluster_sizes) {
    if (size == 0) continue;
    ++clusters;
    total += size;
    size_term += SizeLogSize(size);
  }
  assert(total == num_points);
  (void)total;
  return SphericalGaussianBicFromSizeTerm(size_term, clusters, sse, num_points, dims);
}

void SizeEntropyTracker::Add(double term) {
  // Neumaier's variant of Kahan summation: the rounding error of each addition is kept.
  const double t = sum_ + term;
  if (std::abs(sum_) >= std::abs(term)) {
    compensation_ += (sum_ - t) + term;
  } else {
    compensation_ += (term - t) + sum_;
  }
  sum_ = t;
}

void SizeEntropyTracker::Set(uint32_t cluster, uint64_t size) {
  if (cluster >= sizes_.size()) {
    if (size == 0) return;
    sizes_.resize(std::max<size_t>(size_t{cluster} + 1, 2 * sizes_.size()), 0);
  }
  const uint64_t old = sizes_[cluster];
  if (old == size) return;
  Add(-SizeLogSize(old));
  Add(SizeLogSize(size));
  num_points_ = num_points_ - old + size;
  num_clusters_ = num_clusters_ - (old > 0) + (size > 0);
  sizes_[cluster] = size;
}

void SizeEntropyTracker::Move(uint32_t from, uint32_t to) {
  assert(size(from) >= 1);
  if (from == to) return;
  Set(from, size(from) - 1);
  Set(to, size(to) + 1);
}

BicChoice ChooseByScore(std::span<const uint32_t> cluster_counts, std::vector<double> scores) {
  assert(!cluster_counts.empty() && cluster_counts.size() == scores.size());
  BicChoice choice;
  choice.bic = std::move(scores);
  const std::vector<double>& bic = choice.bic;
  // Levels by cluster count, few to many; later levels first among equal counts, so that
  // the first of a run is the representative on ties.
  std::vector<size_t> order(cluster_counts.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    if (cluster_counts[a] != cluster_counts[b]) return cluster_counts[a] < cluster_counts[b];
    return a > b;
  });
  // One representative per cluster count: the largest score, the later level on ties.
  std::vector<size_t> representative;
  for (size_t level : order) {
    if (!representative.empty() && cluster_counts[representative.back()] == cluster_counts[level]) {
      if (bic[level] > bic[representative.back()]) representative.back() = level;
    } else {
      representative.push_back(level);
    }
  }
  size_t best = representative.front();
  for (size_t level : representative) {
    if (bic[level] > bic[best]) best = level;  // strict: ties keep fewer clusters
  }
  // Undefined levels (-infinity) take no part in the scan, unless all are undefined.
  std::erase_if(representative, [&](size_t level) { return bic[level] == -kInfinity; });
  size_t first_decrease = representative.empty() ? best : representative.back();
  for (size_t i = 0; i + 1 < representative.size(); ++i) {
    if (bic[representative[i + 1]] < bic[representative[i]]) {
      first_decrease = representative[i];
      break;
    }
  }
  // Section 6.6's rule, in the levels' own order: the level before the first whose BIC is
  // below it (degenerate levels skipped); the last defined level where the BIC never falls.
  size_t merging = best;
  bool seen = false;
  for (size_t level = 0; level < bic.size(); ++level) {
    if (bic[level] == -kInfinity) continue;
    if (seen && bic[level] < bic[merging]) break;
    merging = level;
    seen = true;
  }
  choice.merging_first_decrease_level = merging;
  choice.merging_first_decrease_k = cluster_counts[merging];
  choice.best_level = best;
  choice.best_k = cluster_counts[best];
  choice.first_decrease_level = first_decrease;
  choice.first_decrease_k = cluster_counts[first_decrease];
  return choice;
}

absl::StatusOr<BicChoice> ChooseByBic(std::span<const BicLevel> levels, uint64_t num_points,
                                      uint32_t dims) {
  if (levels.empty()) return absl::InvalidArgumentError("levels: none given");
  if (num_points == 0) return absl::InvalidArgumentError("num_points: 0");
  if (dims == 0) return absl::InvalidArgumentError("dims: 0");
  std::vector<uint32_t> counts(levels.size());
  std::vector<double> bic(levels.size());
  for (size_t l = 0; l < levels.size(); ++l) {
    const BicLevel& level = levels[l];
    if (level.clusters < 1 || level.clusters > num_points) {
      return absl::InvalidArgumentError(absl::StrCat("levels: level ", l, " has ", level.clusters,
                                                     " clusters, outside [1, ", num_points,
                                                     "] (the number of points)"));
    }
    if (std::isnan(level.sse) || std::isnan(level.size_term)) {
      return absl::InvalidArgumentError(absl::StrCat("levels: level ", l, " has sse ", level.sse,
                                                     " and size term ", level.size_term));
    }
    counts[l] = level.clusters;
    bic[l] = SphericalGaussianBicFromSizeTerm(level.size_term, level.clusters, level.sse,
                                              num_points, dims);
  }
  return ChooseByScore(counts, std::move(bic));
}

absl::Status BicLevelRecorder::OnStart(std::span<const ClusterId> labels, uint32_t cluster_count,
                                       double energy) {
  if (started_) return absl::FailedPreconditionError("BicLevelRecorder: OnStart called twice");
  if (labels.empty()) return absl::InvalidArgumentError("labels: none");
  for (size_t i = 0; i < labels.size(); ++i) {
    if (!labels[i].valid()) {
      return absl::InvalidArgumentError(absl::StrCat("labels: element ", i, " has no cluster"));
    }
    sizes_.Set(labels[i].value(), sizes_.size(labels[i].value()) + 1);
  }
  if (sizes_.num_clusters() != cluster_count) {
    return absl::InvalidArgumentError(absl::StrCat("cluster_count: ", cluster_count, " but ",
                                                   sizes_.num_clusters(),
                                                   " clusters hold elements"));
  }
  started_ = true;
  levels_.push_back({cluster_count, energy, sizes_.size_term()});
  return absl::OkStatus();
}

absl::Status BicLevelRecorder::OnLevel(const LevelMoves& level) {
  if (!started_) return absl::FailedPreconditionError("BicLevelRecorder: OnLevel before OnStart");
  if (level.element.size() != level.to_cluster.size() ||
      level.element.size() != level.from_cluster.size()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "level ", levels_.size(), ": ", level.element.size(), " elements, ",
        level.to_cluster.size(), " new and ", level.from_cluster.size(), " old clusters"));
  }
  for (size_t i = 0; i < level.element.size(); ++i) {
    const uint32_t from = level.from_cluster[i];
    const uint32_t to = level.to_cluster[i];
    if (to == ClusterId::kInvalidValue) {
      return absl::InvalidArgumentError(absl::StrCat("level ", levels_.size(), ": element ",
                                                     level.element[i], " moves to no cluster"));
    }
    if (sizes_.size(from) == 0) {
      return absl::InvalidArgumentError(absl::StrCat("level ", levels_.size(), ": element ",
                                                     level.element[i], " leaves cluster ", from,
                                                     ", which is empty"));
    }
    sizes_.Move(from, to);
  }
  if (sizes_.num_clusters() != level.cluster_count) {
    return absl::InvalidArgumentError(
        absl::StrCat("level ", levels_.size(), ": cluster_count ", level.cluster_count, " but ",
                     sizes_.num_clusters(), " clusters hold elements"));
  }
  levels_.push_back({level.cluster_count, level.energy, sizes_.size_term()});
  return absl::OkStatus();
}

}  // namespace mlclust
