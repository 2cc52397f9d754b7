// The one "renumber labels by first appearance": labels (any hashable id) become dense ids
// 0..k-1, the first distinct label met becoming 0, the next 1, and so on.
#ifndef MLCLUST_CORE_BASE_RENUMBER_H_
#define MLCLUST_CORE_BASE_RENUMBER_H_

#include <cstdint>
#include <span>
#include <vector>

#include "absl/container/flat_hash_map.h"

namespace mlclust {

template <typename Label>
struct Renumbering {
  std::vector<uint32_t> dense;  // per element: its label's dense id
  std::vector<Label> original;  // per dense id: the label it stands for

  uint32_t size() const { return static_cast<uint32_t>(original.size()); }
};

// O(n) expected, one hash-map entry per distinct label.
template <typename Label>
Renumbering<Label> RenumberByFirstAppearance(std::span<const Label> labels) {
  Renumbering<Label> result;
  result.dense.resize(labels.size());
  absl::flat_hash_map<Label, uint32_t> index;
  for (size_t i = 0; i < labels.size(); ++i) {
    auto [it, inserted] = index.try_emplace(labels[i], result.size());
    if (inserted) result.original.push_back(labels[i]);
    result.dense[i] = it->second;
  }
  return result;
}

}  // namespace mlclust

#endif  // MLCLUST_CORE_BASE_RENUMBER_H_
