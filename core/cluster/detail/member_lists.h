// What the mesh and point spaces of the multilevel engine (core/cluster/multilevel.cc,
// core/cluster/point_clustering.cc) share for their clusters' elements: a list per cluster
// and each element's index in its list, so that an element changes cluster in O(1).
#ifndef MLCLUST_CORE_CLUSTER_DETAIL_MEMBER_LISTS_H_
#define MLCLUST_CORE_CLUSTER_DETAIL_MEMBER_LISTS_H_

#include <cstdint>
#include <vector>

namespace mlclust::detail {

// Moves `element` from `members[from]` to the end of `members[to]`: the last element of
// `from` takes its place there (a swap-remove), and `position` follows both.
inline void MoveMember(std::vector<std::vector<uint32_t>>& members, std::vector<uint32_t>& position,
                       uint32_t element, uint32_t from, uint32_t to) {
  std::vector<uint32_t>& list = members[from];
  const uint32_t at = position[element];
  list[at] = list.back();
  position[list[at]] = at;
  list.pop_back();
  position[element] = static_cast<uint32_t>(members[to].size());
  members[to].push_back(element);
}

}  // namespace mlclust::detail

#endif  // MLCLUST_CORE_CLUSTER_DETAIL_MEMBER_LISTS_H_
