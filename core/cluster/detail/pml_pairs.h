// Which mutual optimal dual edges one PML level collapses (Alg. 5.3 and our variant), the
// one rule for the mesh and the point multilevel engines.
#ifndef MLCLUST_CORE_CLUSTER_DETAIL_PML_PAIRS_H_
#define MLCLUST_CORE_CLUSTER_DETAIL_PML_PAIRS_H_

#include <algorithm>
#include <cstdint>
#include <utility>
#include <vector>

namespace mlclust {

// kAll: every mutual pair of the level (Alg. 5.3). kCheaperHalf (ours): only the pairs
// that cost at most the level's median mutual pair. Near the data's own scale the mutual
// pairs mix pieces of one cluster (cheap) with whole clusters (dear); collapsing all of
// them in one level merges whole clusters while pieces remain.
enum class PmlPairRule { kCheaperHalf, kAll };

namespace detail {

// Keeps, of `pairs` (each a mutual pair (a, b) with merge cost cost_of(a)), those `rule`
// collapses, in their given order. kCheaperHalf keeps every pair that costs at most the
// median (the pair at index size / 2 in cost order), so at least one. `costs` is scratch
// (a caller that selects every level keeps it, saving a large allocation per level).
template <typename CostOf>
void SelectPmlPairs(PmlPairRule rule, const CostOf& cost_of,
                    std::vector<std::pair<uint32_t, uint32_t>>& pairs, std::vector<double>& costs) {
  if (rule == PmlPairRule::kAll || pairs.empty()) return;
  costs.clear();
  for (const auto& pair : pairs) costs.push_back(cost_of(pair.first));
  std::nth_element(costs.begin(), costs.begin() + costs.size() / 2, costs.end());
  const double limit = costs[costs.size() / 2];
  pairs.erase(std::remove_if(pairs.begin(), pairs.end(),
                             [&](const auto& pair) { return !(cost_of(pair.first) <= limit); }),
              pairs.end());
}
template <typename CostOf>
void SelectPmlPairs(PmlPairRule rule, const CostOf& cost_of,
                    std::vector<std::pair<uint32_t, uint32_t>>& pairs) {
  std::vector<double> costs;
  SelectPmlPairs(rule, cost_of, pairs, costs);
}

}  // namespace detail
}  // namespace mlclust

#endif  // MLCLUST_CORE_CLUSTER_DETAIL_PML_PAIRS_H_
