// The relative tolerance of an improvement. Cluster sums carry rounding of about 1e-16
// relative, so a move or a choice counts as lowering the energy only where it gains more
// than this share of the energy it changes: EMLO's moves (Alg. 3.3), BB's decide rule
// (Alg. 5.1, boundary_based.h DecideBoundaryMove) and ML's local optimisation.
#ifndef MLCLUST_CORE_BASE_TOLERANCE_H_
#define MLCLUST_CORE_BASE_TOLERANCE_H_

namespace mlclust {

inline constexpr double kRelativeImprovement = 1e-12;

}  // namespace mlclust

#endif  // MLCLUST_CORE_BASE_TOLERANCE_H_
