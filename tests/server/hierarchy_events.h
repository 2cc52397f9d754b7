// A small hierarchy as a job's events, for the registry's tests and fuzz/fuzz_watch_cancel.cc:
// level 0 has labels 0..n-1; level l (1..n-1) moves element l to cluster 0.
#ifndef MLCLUST_TESTS_SERVER_HIERARCHY_EVENTS_H_
#define MLCLUST_TESTS_SERVER_HIERARCHY_EVENTS_H_

#include <cstdint>

#include "mlclust/v1/mlclust.pb.h"

namespace mlclust::server::test_data {

// The snapshot of level 0.
inline v1::JobEvent HierarchySnapshot(uint32_t n) {
  v1::JobEvent snapshot;
  snapshot.mutable_snapshot()->set_total_elements(n);
  snapshot.mutable_snapshot()->set_cluster_count(n);
  for (uint32_t i = 0; i < n; ++i) snapshot.mutable_snapshot()->add_labels(i);
  return snapshot;
}

// Levels 1..n-1 in one batch.
inline v1::JobEvent HierarchyLevels(uint32_t n) {
  v1::JobEvent levels;
  v1::LevelBatch* batch = levels.mutable_levels();
  batch->set_first_level(1);
  for (uint32_t l = 1; l < n; ++l) {
    batch->add_cluster_count(n - l);
    batch->add_energy(l);
    batch->add_element(l);
    batch->add_to_cluster(0);
    batch->add_from_cluster(l);
    batch->add_triplet_end(l);
  }
  return levels;
}

}  // namespace mlclust::server::test_data

#endif  // MLCLUST_TESTS_SERVER_HIERARCHY_EVENTS_H_
