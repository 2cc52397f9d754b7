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
//
// For PML (ours): RecordMerges records a level's merges of disjoint pairs at once, and
// Squash can take a `for_blocks` that runs its blocks in parallel (the driver's TBB; this
// layer has no threads of its own). Both give exactly what the one-by-one calls give.
#ifndef MLCLUST_CORE_HIERARCHY_LEVEL_RECORDER_H_
#define MLCLUST_CORE_HIERARCHY_LEVEL_RECORDER_H_

#include <algorithm>
#include <cassert>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "core/base/compensated_sum.h"
#include "core/hierarchy/hierarchy.h"

namespace mlclust {

class LevelRecorder {
 public:
  // Runs body(begin, end) over the indices [0, n) in blocks: the default runs one block on
  // the calling thread; a driver may pass one that runs blocks in parallel.
  struct InOrder {
    template <typename Body>
    void operator()(size_t n, const Body& body) const {
      if (n > 0) body(size_t{0}, n);
    }
  };

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
  // A level that starts with merges of disjoint pairs (keep, gone): the same as, pair after
  // pair, Touch(keep), Touch(gone) and RecordMove(e, gone) for every e of members_of(gone)
  // (a span of elements), with the pairs' work spread by `for_blocks`. Only at the start of
  // a level (nothing touched or moved yet): false otherwise, and nothing is recorded.
  template <typename EnergyOf, typename MembersOf, typename ForBlocks = InOrder>
  bool RecordMerges(std::span<const std::pair<uint32_t, uint32_t>> keep_gone,
                    const EnergyOf& energy_of, const MembersOf& members_of,
                    const ForBlocks& for_blocks = {}) {
    if (!affected_.empty() || !moved_.empty()) return false;
    const size_t pairs = keep_gone.size();
    affected_.resize(2 * pairs);
    offset_.assign(pairs + 1, 0);
    for_blocks(pairs, [&](size_t begin, size_t end) {
      for (size_t i = begin; i < end; ++i) {
        const auto [keep, gone] = keep_gone[i];
        assert(!touched_mark_[keep] && !touched_mark_[gone]);  // the pairs are disjoint
        affected_[2 * i] = keep;
        affected_[2 * i + 1] = gone;
        touched_mark_[keep] = touched_mark_[gone] = 1;
        energy_before_[keep] = energy_of(keep);
        energy_before_[gone] = energy_of(gone);
        offset_[i + 1] = members_of(gone).size();
      }
    });
    for (size_t i = 0; i < pairs; ++i) offset_[i + 1] += offset_[i];
    moved_.resize(offset_[pairs]);
    for_blocks(pairs, [&](size_t begin, size_t end) {
      for (size_t i = begin; i < end; ++i) {
        const uint32_t gone = keep_gone[i].second;
        size_t at = offset_[i];
        for (uint32_t e : members_of(gone)) {
          origin_[e] = gone;
          moved_[at++] = e;
        }
      }
    });
    return true;
  }

  // For moves applied in parallel on distinct clusters and elements: Touch and RecordMove
  // without their lists, each saying whether it was the first (touch of c / move of e in
  // the level); the caller then lists those, in the order the one-by-one calls would have.
  template <typename EnergyOf>
  bool TouchUnlisted(uint32_t c, const EnergyOf& energy_of) {
    if (touched_mark_[c]) return false;
    touched_mark_[c] = 1;
    energy_before_[c] = energy_of(c);
    return true;
  }
  void ListTouched(uint32_t c) { affected_.push_back(c); }
  bool RecordMoveUnlisted(uint32_t element, uint32_t from) {
    if (origin_[element] != kNotMoved) return false;
    origin_[element] = from;
    return true;
  }
  void ListMoved(uint32_t element) { moved_.push_back(element); }

  // The clusters touched in this level, in order of first touch.
  std::span<const uint32_t> affected() const { return affected_; }

  // Ends the level's accounting: the energy takes energy_of(c) - (c's energy before) for
  // each touched c; each moved element whose label_of(e) differs from its cluster at the
  // previous level becomes a triplet (id_of(e), label_of(e), previous cluster).
  // With `for_blocks`, the moved elements are squashed in fixed blocks of kSquashBlock
  // (label_of and id_of are then called from its threads), joined in order.
  template <typename EnergyOf, typename LabelOf, typename IdOf, typename ForBlocks = InOrder>
  void Squash(const EnergyOf& energy_of, const LabelOf& label_of, const IdOf& id_of,
              const ForBlocks& for_blocks = {}) {
    for (uint32_t c : affected_) {
      energy_.Add(energy_of(c) - energy_before_[c]);
      touched_mark_[c] = 0;
    }
    if (moved_.size() >= 2 * kSquashBlock) {
      SquashInBlocks(label_of, id_of, for_blocks);
      return;
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
  static constexpr size_t kSquashBlock = 8192;

  // Squash's element part over blocks of moved_: count the triplets per block, then fill
  // each block's share at its offset; the same triplets in the same order as one loop.
  template <typename LabelOf, typename IdOf, typename ForBlocks>
  void SquashInBlocks(const LabelOf& label_of, const IdOf& id_of, const ForBlocks& for_blocks) {
    const size_t blocks = (moved_.size() + kSquashBlock - 1) / kSquashBlock;
    offset_.assign(blocks + 1, 0);
    for_blocks(blocks, [&](size_t begin, size_t end) {
      for (size_t b = begin; b < end; ++b) {
        const size_t last = std::min(moved_.size(), (b + 1) * kSquashBlock);
        size_t count = 0;
        for (size_t i = b * kSquashBlock; i < last; ++i) {
          count += label_of(moved_[i]) != origin_[moved_[i]] ? 1 : 0;
        }
        offset_[b + 1] = count;
      }
    });
    for (size_t b = 0; b < blocks; ++b) offset_[b + 1] += offset_[b];
    element_.resize(offset_[blocks]);
    to_.resize(offset_[blocks]);
    from_.resize(offset_[blocks]);
    for_blocks(blocks, [&](size_t begin, size_t end) {
      for (size_t b = begin; b < end; ++b) {
        const size_t last = std::min(moved_.size(), (b + 1) * kSquashBlock);
        size_t at = offset_[b];
        for (size_t i = b * kSquashBlock; i < last; ++i) {
          const uint32_t e = moved_[i];
          const uint32_t label = label_of(e);
          if (label != origin_[e]) {
            element_[at] = id_of(e);
            to_[at] = label;
            from_[at] = origin_[e];
            ++at;
          }
          origin_[e] = kNotMoved;
        }
      }
    });
    moved_.clear();
  }

  std::vector<uint32_t> origin_;  // per element: its cluster at the previous level, or none
  std::vector<uint32_t> moved_;   // the elements with an origin
  std::vector<uint8_t> touched_mark_;
  std::vector<uint32_t> affected_;
  std::vector<double> energy_before_;
  std::vector<uint32_t> element_, to_, from_;
  std::vector<size_t> offset_;  // RecordMerges' and SquashInBlocks' scratch
  detail::CompensatedSum energy_;
  uint64_t moves_ = 0;
};

}  // namespace mlclust

#endif  // MLCLUST_CORE_HIERARCHY_LEVEL_RECORDER_H_
