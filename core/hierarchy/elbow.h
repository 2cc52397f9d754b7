// The elbow of an energy curve over the levels of a hierarchy (dissertation section 4.4).
#ifndef MLCLUST_CORE_HIERARCHY_ELBOW_H_
#define MLCLUST_CORE_HIERARCHY_ELBOW_H_

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace mlclust {

// Section 4.4: the cluster counts where the energy curve bends, strongest first. A level
// with k clusters is an elbow when the next level's energy is more than `jump` times its
// own (the curve is at its flattest before a natural grouping is broken up); levels whose
// energy is below `significance` times the largest are rounding noise and skipped. At most
// `max_elbows`, ordered by the size of the jump. `cluster_count` and `energy` are per
// level, in level order (cluster counts falling).
std::vector<uint32_t> FindElbows(std::span<const uint32_t> cluster_count,
                                 std::span<const double> energy, double jump = 2.0,
                                 double significance = 1e-4, size_t max_elbows = 5);

}  // namespace mlclust

#endif  // MLCLUST_CORE_HIERARCHY_ELBOW_H_
