// The elbow of an energy curve over the levels of a hierarchy (dissertation section 4.4).
#ifndef MLCLUST_CORE_HIERARCHY_ELBOW_H_
#define MLCLUST_CORE_HIERARCHY_ELBOW_H_

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace mlclust {

struct ElbowOptions {
  // The next coarser level's energy must be more than `jump` times this level's.
  double jump = 2.0;
  // Energies below `significance` times the largest count as zero: they are floored there
  // (not skipped), so the ratio against a zero level is large but finite, and a step from
  // rounding noise to more rounding noise is no elbow.
  double significance = 1e-3;
  size_t max_elbows = 5;
};

// Section 4.4 (l. 1815): with a well-chosen energy the energy "remains zero until the 'true'
// number of clusters present in the model is reached, followed by a fast increase as the
// number of clusters decreases". A level with k clusters is an elbow when, with E_max the
// largest energy and floor = significance * E_max,
//   E(next level) > jump * max(E(level), floor).
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
