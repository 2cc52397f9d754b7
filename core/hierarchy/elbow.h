// The elbow of an energy curve over the levels of a hierarchy (dissertation section 4.4).
#ifndef MLCLUST_CORE_HIERARCHY_ELBOW_H_
#define MLCLUST_CORE_HIERARCHY_ELBOW_H_

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace mlclust {

struct ElbowOptions {
  enum class Rule {
    // Section 4.4 (l. 1815), the default: only the end of a (near) zero plateau is an
    // elbow, i.e. a level whose energy still reads as zero (`plateau`), then a jump.
    // A curve that rises steadily from zero (a shape the energy cannot fit exactly, such
    // as fandisk's cylinders with the planar energy) has none.
    kEndOfZeroPlateau,
    // Ours: any level whose next energy jumps by more than `jump`, plateau or not (knees
    // of curves that are never zero, e.g. CVD or the points' variance).
    kAnyJump,
  };
  Rule rule = Rule::kEndOfZeroPlateau;
  // The next coarser level's energy must be more than `jump` times this level's.
  double jump = 2.0;
  // kEndOfZeroPlateau: the energy "remains zero" while it is at most `plateau` times the
  // largest (2 %: what reads as zero on the text's linear plots; a finely tessellated
  // sphere is not exactly a sphere, e.g. the true three patches of TwoSpheresAndAPlane at
  // 24 segments have 1.2 % of the one-cluster energy).
  double plateau = 0.02;
  // Energies below `significance` times the largest count as zero: they are floored there
  // (not skipped), so the ratio against a zero level is large but finite, and a step from
  // rounding noise to more rounding noise is no elbow.
  double significance = 1e-3;
  size_t max_elbows = 5;
};

// Section 4.4 (l. 1815): with a well-chosen energy the energy "remains zero until the 'true'
// number of clusters present in the model is reached, followed by a fast increase as the
// number of clusters decreases". With E_max the largest energy and floor = significance *
// E_max, a level with k clusters is an elbow when
//   E(next level) > jump * max(E(level), floor)                 (kAnyJump, ours)
//   the same and E(level) <= plateau * E_max                     (kEndOfZeroPlateau)
// So the end of a (near) zero plateau is an elbow: a cube with the planar energy at 6, a
// solid of s spheres and planes with the sphere energy at s + planes.
//
// Returns at most `max_elbows` cluster counts in level order, i.e. in the order the
// agglomeration meets them, from many clusters to few: the first is the finest grouping
// the energy supports, the one the text reads off the curve. `cluster_count` and `energy`
// are per level, in level order (cluster counts falling); extra entries of the longer one
// are ignored.
std::vector<uint32_t> FindElbows(std::span<const uint32_t> cluster_count,
                                 std::span<const double> energy, const ElbowOptions& options = {});

}  // namespace mlclust

#endif  // MLCLUST_CORE_HIERARCHY_ELBOW_H_
