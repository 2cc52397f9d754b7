// HC: hierarchical face clustering by greedy merges only (Alg. 2.3).
//
// Starts with one cluster per face and repeatedly merges the pair of adjacent clusters
// with the smallest merge cost E(A u B) - E(A) - E(B) (eq. 4.3) until one cluster is left
// (or, on a mesh with several connected components, one per component).
#ifndef MLCLUST_CORE_HIERARCHICAL_CLUSTERING_H_
#define MLCLUST_CORE_HIERARCHICAL_CLUSTERING_H_

#include <cstdint>

#include "absl/status/status.h"
#include "core/face_measures.h"
#include "core/hierarchy.h"
#include "core/mesh.h"

namespace mlclust {

struct HierarchicalClusteringOptions {
  // Stop once this many clusters are left (>= 1).
  uint32_t min_clusters = 1;
};

struct HierarchicalClusteringSummary {
  uint32_t levels = 0;          // levels reported to the sink, level 0 included
  uint32_t final_clusters = 0;  // clusters at the last level
  uint64_t moves = 0;           // triplets reported in all
};

// Reports level 0 (every face its own cluster, cluster id = face id, energy 0) and then
// one level per merge to `sink`. Cluster ids stay face ids: a merge keeps the id of the
// larger cluster (by face count; the smaller id on a tie) and moves the other's faces,
// so each face moves O(log n) times and the log stays O(n log n).
// Ties in cost are broken by the smaller pair of ids, so runs are deterministic.
// Returns the sink's status if it stops the run, INVALID_ARGUMENT for bad options.
absl::StatusOr<HierarchicalClusteringSummary> RunHierarchicalClustering(
    const FaceMeasures& measures, const FaceAdjacency& adjacency,
    const HierarchicalClusteringOptions& options, LevelSink& sink);

// Level 0 of a face clustering in which every face is its own cluster.
std::vector<ClusterId> SingletonLabels(size_t num_faces);

}  // namespace mlclust

#endif  // MLCLUST_CORE_HIERARCHICAL_CLUSTERING_H_
