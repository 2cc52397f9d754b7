// The refresh of one cluster's local neighbours (eq. 6.1) on flat tables, shared by the
// CPU's point clusters (PointClusters::RefreshNeighbours, ln_kmeans_stages.h) and the
// GPU's voxel start (gpu/stages/points_multilevel_gpu.cc), which must agree bit for bit
// so that the GPU's first level is the CPU's. Internal to core/cluster.
#ifndef MLCLUST_CORE_CLUSTER_DETAIL_LOCAL_NEIGHBOURS_H_
#define MLCLUST_CORE_CLUSTER_DETAIL_LOCAL_NEIGHBOURS_H_

#include <algorithm>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "core/cluster/detail/ode_heap.h"
#include "core/cluster/point_clustering.h"

namespace mlclust::detail {

// What RefreshLocalNeighbours keeps between calls: a stamp per cluster (each candidate is
// taken once without sorting: with 2d neighbours each there are up to 4d^2 of them,
// mostly repeats) and the best distance per subspace.
struct LocalNeighbourScratch {
  explicit LocalNeighbourScratch(uint32_t clusters) : seen(clusters, 0) {}
  std::vector<uint32_t> seen;
  uint32_t now = 0;
  std::vector<double> best;
};

// Eq. 6.1 neighbours of cluster `c`: its row of `neighbours` (k x 2d, kNoCluster where
// none) becomes, per subspace (SubspaceIndex), the nearest centroid (`centroids`, k x d)
// among the clusters with points (`counts`) in `candidates` (any the caller adds), c's
// neighbours and theirs; equal distances to the smaller id. Leaves `candidates` empty.
template <typename Count>
void RefreshLocalNeighbours(uint32_t c, uint32_t d, std::span<const double> centroids,
                            std::span<const Count> counts, std::span<uint32_t> neighbours,
                            std::vector<uint32_t>& candidates, LocalNeighbourScratch& scratch) {
  const size_t slots = size_t{2} * d;
  const std::span<uint32_t> out = neighbours.subspan(c * slots, slots);
  for (const uint32_t n : out) {
    if (n == kNoCluster) continue;
    candidates.push_back(n);
    for (const uint32_t nn : neighbours.subspan(n * slots, slots)) {
      if (nn != kNoCluster) candidates.push_back(nn);
    }
  }
  if (++scratch.now == 0) {
    std::fill(scratch.seen.begin(), scratch.seen.end(), 0);
    scratch.now = 1;
  }
  size_t unique = 0;
  for (const uint32_t n : candidates) {
    if (n == kNoCluster || scratch.seen[n] == scratch.now) continue;
    scratch.seen[n] = scratch.now;
    candidates[unique++] = n;
  }
  candidates.resize(unique);
  std::fill(out.begin(), out.end(), kNoCluster);
  scratch.best.assign(slots, std::numeric_limits<double>::infinity());
  const std::span<const double> from = centroids.subspan(size_t{c} * d, d);
  for (const uint32_t n : candidates) {
    if (n == c || counts[n] == 0) continue;
    const std::span<const double> to = centroids.subspan(size_t{n} * d, d);
    const uint32_t s = SubspaceIndex(from, to);
    double dist = 0;
    for (uint32_t j = 0; j < d; ++j) {
      const double diff = from[j] - to[j];
      dist += diff * diff;
    }
    if (dist < scratch.best[s] || (dist == scratch.best[s] && n < out[s])) {
      scratch.best[s] = dist;
      out[s] = n;
    }
  }
  candidates.clear();
}

}  // namespace mlclust::detail

#endif  // MLCLUST_CORE_CLUSTER_DETAIL_LOCAL_NEIGHBOURS_H_
