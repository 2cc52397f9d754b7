// The hierarchy log (section 4.3): every level of a clustering run as the list of elements
// that changed cluster, as triplets (element, new cluster, old cluster).
//
// Level 0 is the start (labels given in full). Level l > 0 holds the moves that turn the
// labels of level l - 1 into those of level l; an element appears at most once per level.
// Applying a level's triplets with `to_cluster` steps forward, with `from_cluster` back.
// Memory is proportional to the number of moves, not to levels x elements.
#ifndef MLCLUST_CORE_HIERARCHY_HIERARCHY_H_
#define MLCLUST_CORE_HIERARCHY_HIERARCHY_H_

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "core/base/ids.h"

namespace mlclust {

// One level as a driver reports it. The spans are only valid during the call.
struct LevelMoves {
  uint32_t level = 0;  // the driver's level number (1, 2, ...); 0 where it does not say
  uint32_t cluster_count = 0;
  double energy = 0;
  std::span<const uint32_t> element;       // element ids (faces or points)
  std::span<const uint32_t> to_cluster;    // its cluster at this level
  std::span<const uint32_t> from_cluster;  // its cluster at the previous level
};

// Receives the levels of a run in order: OnStart once with level 0 in full, then OnLevel
// after each later level. A non-OK status (for example CANCELLED) stops the driver, which
// returns that status.
class LevelSink {
 public:
  virtual ~LevelSink() = default;
  virtual absl::Status OnStart(std::span<const ClusterId> labels, uint32_t cluster_count,
                               double energy) = 0;
  virtual absl::Status OnLevel(const LevelMoves& level) = 0;
};

class HierarchyLog : public LevelSink {
 public:
  // Sets level 0: one label per element. FAILED_PRECONDITION if called twice.
  absl::Status OnStart(std::span<const ClusterId> labels, uint32_t cluster_count,
                       double energy) override;

  // Appends a level. FAILED_PRECONDITION before OnStart; INVALID_ARGUMENT if the three spans differ
  // in length, an element is out of range, or an element appears twice in the level.
  absl::Status OnLevel(const LevelMoves& level) override;

  size_t num_elements() const { return start_labels_.size(); }
  size_t num_levels() const { return cluster_count_.size(); }
  uint32_t cluster_count(size_t level) const { return cluster_count_[level]; }
  double energy(size_t level) const { return energy_[level]; }
  size_t num_moves() const { return element_.size(); }
  std::span<const ClusterId> start_labels() const { return start_labels_; }

  // The moves of `level` (> 0).
  LevelMoves level(size_t level) const;

  // Steps `labels`, currently at `from_level`, to `to_level` (either direction) in
  // O(moves in between). DATA_LOSS if a triplet does not match the labels it is applied
  // to (the labels were not at `from_level`); OUT_OF_RANGE for a level past the end.
  absl::Status StepLabels(std::vector<ClusterId>& labels, size_t from_level, size_t to_level) const;

  // The labels at `level`, rebuilt from level 0.
  absl::StatusOr<std::vector<ClusterId>> LabelsAt(size_t level) const;

  // The first level whose cluster count is <= k, or nullopt if none.
  std::optional<size_t> FirstLevelWithAtMost(uint32_t k) const;
  // The last level whose cluster count is exactly k, or nullopt if none.
  std::optional<size_t> LastLevelWith(uint32_t k) const;

 private:
  std::vector<ClusterId> start_labels_;
  std::vector<uint32_t> cluster_count_;
  std::vector<double> energy_;
  std::vector<uint64_t> level_end_;  // moves of level l are [level_end_[l-1], level_end_[l])
  std::vector<uint32_t> element_;
  std::vector<uint32_t> to_cluster_;
  std::vector<uint32_t> from_cluster_;
  std::vector<uint32_t> seen_in_level_;  // scratch for the duplicate check
  uint32_t stamp_ = 0;
};

}  // namespace mlclust

#endif  // MLCLUST_CORE_HIERARCHY_HIERARCHY_H_
