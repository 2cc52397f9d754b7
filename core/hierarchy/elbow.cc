#include "core/hierarchy/elbow.h"

#include <algorithm>

namespace mlclust {

std::vector<uint32_t> FindElbows(std::span<const uint32_t> cluster_count,
                                 std::span<const double> energy, const ElbowOptions& options) {
  const size_t levels = std::min(cluster_count.size(), energy.size());
  std::vector<uint32_t> elbows;
  if (levels < 2 || options.max_elbows == 0) return elbows;
  const double largest = *std::max_element(energy.begin(), energy.begin() + levels);
  if (!(largest > 0)) return elbows;  // a flat zero curve has no elbow
  const double floor = options.significance * largest;
  for (size_t l = 0; l + 1 < levels && elbows.size() < options.max_elbows; ++l) {
    if (options.rule == ElbowOptions::Rule::kEndOfZeroPlateau &&
        energy[l] > options.plateau * largest) {
      continue;
    }
    const double here = std::max(energy[l], floor);
    const double next = energy[l + 1];
    if (next > options.jump * here) {
      elbows.push_back(cluster_count[l]);
    }
  }
  return elbows;
}

}  // namespace mlclust
