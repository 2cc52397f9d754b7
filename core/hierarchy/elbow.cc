#include "core/hierarchy/elbow.h"

#include <algorithm>
#include <utility>

namespace mlclust {

std::vector<uint32_t> FindElbows(std::span<const uint32_t> cluster_count,
                                 std::span<const double> energy, double jump, double significance,
                                 size_t max_elbows) {
  std::vector<std::pair<double, uint32_t>> candidates;  // strength, cluster count
  if (energy.empty()) return {};
  const double largest = *std::max_element(energy.begin(), energy.end());
  for (size_t l = 0; l + 1 < energy.size(); ++l) {
    // Levels whose energy is a negligible share of the largest are rounding noise: there
    // every merge multiplies the energy.
    if (!(energy[l] > significance * largest)) continue;
    const double strength = energy[l + 1] / energy[l];
    if (strength > jump) candidates.push_back({strength, cluster_count[l]});
  }
  std::stable_sort(candidates.begin(), candidates.end(),
                   [](const auto& x, const auto& y) { return x.first > y.first; });
  std::vector<uint32_t> elbows;
  for (const auto& [strength, k] : candidates) {
    if (elbows.size() == max_elbows) break;
    elbows.push_back(k);
  }
  return elbows;
}

}  // namespace mlclust
