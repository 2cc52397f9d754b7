// Turns a driver's moves into hierarchy levels (section 4.3): the bookkeeping every
// driver that reports levels shares, multilevel or single-level.
//
// Within a level the driver calls
//   Touch(c, energy_of)     before it changes cluster c (a merge, a move in or out), so
//                           the cluster's energy from before the level is kept;
//   RecordMove(e, from)     when element e leaves cluster `from` (only the first call per
//                           element and level counts: its cluster at the previous level);
// and at the end of the level
//   Squash(energy_of, label_of, id_of)  adds the touched clusters' energy changes to the
//                           running energy and squashes the moves into triplets (an
//                           element that came back to its cluster drops out);
//   Emit(sink, level, clusters)         reports the level and starts the next.
// Between Squash and Emit, affected() still lists the clusters the level touched.
//
// The energy is a compensated running sum of per-cluster changes, never re-scanned.
#ifndef MLCLUST_CORE_HIERARCHY_LEVEL_RECORDER_H_
#define MLCLUST_CORE_HIERARCHY_LEVEL_RECORDER_H_

#include <cstdint>
#include <span>
#include <vector>

#include "absl/status/status.h"
#include "core/base/compensated_sum.h"
#include "core/hierarchy/hierarchy.h"

namespace mlclust {

class LevelRecorder {
 public:
  // Elements are indices below `num_elements`, clusters below `num_clusters`.
  LevelRecorder(size_t num_elements, uint32_t num_clusters)
      : origin_(num_elements, kNotMoved),
        touched_mark_(num_clusters, 0),
        energy_before_(num_clusters, 0.0) {}

  // The running energy starts at `energy` (the energy of level 0).
  void Reset(double energy) { energy_.Reset(energy); }
  double energy() const { return energy_.value(); }
  // Triplets reported so far.
  uint64_t moves() const { return moves_; }

  // Cluster c is about to change: keeps energy_of(c) from before the level (called only
  // for the first touch of c in a level).
  template <typename EnergyOf>
  void Touch(uint32_t c, const EnergyOf& energy_of) {
    if (touched_mark_[c]) return;
    touched_mark_[c] = 1;
    affected_.push_back(c);
    energy_before_[c] = energy_of(c);
  }
  // Element `element` leaves cluster `from`.
  void RecordMove(uint32_t element, uint32_t from) {
    if (origin_[element] == kNotMoved) {
      origin_[element] = from;
      moved_.push_back(element);
    }
  }
  // The clusters touched in this level, in order of first touch.
  std::span<const uint32_t> affected() const { return affected_; }

  // Ends the level's accounting: the energy takes energy_of(c) - (c's energy before) for
  // each touched c; each moved element whose label_of(e) differs from its cluster at the
  // previous level becomes a triplet (id_of(e), label_of(e), previous cluster).
  template <typename EnergyOf, typename LabelOf, typename IdOf>
  void Squash(const EnergyOf& energy_of, const LabelOf& label_of, const IdOf& id_of) {
    for (uint32_t c : affected_) {
      energy_.Add(energy_of(c) - energy_before_[c]);
      touched_mark_[c] = 0;
    }
    element_.clear();
    to_.clear();
    from_.clear();
    for (uint32_t e : moved_) {
      const uint32_t label = label_of(e);
      if (label != origin_[e]) {
        element_.push_back(id_of(e));
        to_.push_back(label);
        from_.push_back(origin_[e]);
      }
      origin_[e] = kNotMoved;
    }
    moved_.clear();
  }

  // Reports the squashed level as level `level` with `clusters` clusters, and clears the
  // level. The sink's status (a non-OK one stops the driver).
  absl::Status Emit(LevelSink& sink, uint32_t level, uint32_t clusters) {
    affected_.clear();
    LevelMoves moves;
    moves.level = level;
    moves.cluster_count = clusters;
    moves.energy = energy_.value();
    moves.element = element_;
    moves.to_cluster = to_;
    moves.from_cluster = from_;
    moves_ += element_.size();
    return sink.OnLevel(moves);
  }

 private:
  static constexpr uint32_t kNotMoved = 0xffffffffu;

  std::vector<uint32_t> origin_;  // per element: its cluster at the previous level, or none
  std::vector<uint32_t> moved_;   // the elements with an origin
  std::vector<uint8_t> touched_mark_;
  std::vector<uint32_t> affected_;
  std::vector<double> energy_before_;
  std::vector<uint32_t> element_, to_, from_;
  detail::CompensatedSum energy_;
  uint64_t moves_ = 0;
};

}  // namespace mlclust

#endif  // MLCLUST_CORE_HIERARCHY_LEVEL_RECORDER_H_
