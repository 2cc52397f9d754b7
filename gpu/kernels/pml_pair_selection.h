// The host side of one GPU PML collapse, shared by the mesh (pml_levels.h) and the point
// (points_levels.h) engines: which of a level's mutual pairs the merge pass collapses.
#ifndef MLCLUST_GPU_KERNELS_PML_PAIR_SELECTION_H_
#define MLCLUST_GPU_KERNELS_PML_PAIR_SELECTION_H_

#include <cstdint>
#include <span>
#include <vector>

#include "core/cluster/detail/pml_pairs.h"

namespace mlclust::gpu {

// The CPU engine's selection (ParallelMerges) on the level's `ids` (2 per pair: the two
// clusters) and `values` (3 per pair, the first the merge cost): the pair rule, then the
// cheapest (cost, then pair) down to `floor` clusters from `clusters`. Sets `selected`
// (one flag per pair, in the GPU's pair order) and returns how many pairs it keeps.
uint32_t SelectGpuPmlPairs(PmlPairRule rule, uint32_t clusters, uint32_t floor,
                           std::span<const uint32_t> ids, std::span<const double> values,
                           std::vector<uint32_t>& selected);

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_KERNELS_PML_PAIR_SELECTION_H_
