// Planar Δ_merging (dissertation section 3.3.2, l. 1285 and Fig. 3.17c): a post-pass over a
// planar clustering that merges neighbouring clusters whose representative normals differ
// by less than an angle Δ_merging, for planar patches that the optimisation left split in
// several clusters (poor seeding, or strictly planar regions where every boundary has zero
// energy).
//
// The representative normal of a cluster is eq. 3.37, N_i = Σ ρ_j A_j n_j / ‖Σ ρ_j A_j n_j‖
// over its faces (A_j area, n_j unit normal, ρ_j density, 1 unless given). Neighbouring:
// sharing a mesh edge.
//
// The text does not say in which order merges happen or whether a merged cluster's normal
// is recomputed. Ours: the pair of neighbours with the smallest angle merges first, and the
// merged cluster's normal is eq. 3.37 over its faces (its sums added), against which its
// neighbours are measured again. So a slowly curving surface does not chain into one
// cluster, as merging every pair whose original normals are close (a transitive closure)
// would do: a strip of planar clusters turning 0.8° each stays split at Δ = 1° after its
// neighbours are paired (tests/core/cluster/planar_merging_test.cc).
#ifndef MLCLUST_CORE_CLUSTER_PLANAR_MERGING_H_
#define MLCLUST_CORE_CLUSTER_PLANAR_MERGING_H_

#include <atomic>
#include <span>
#include <vector>

#include "absl/status/statusor.h"
#include "core/base/ids.h"
#include "core/mesh/mesh.h"

namespace mlclust {

struct PlanarMergingOptions {
  // Δ_merging in degrees, in [0, 180]: neighbours whose normals make a smaller angle merge.
  // 0 merges nothing. The text's example (Fig. 3.17c) uses 1°.
  double max_angle_degrees = 1.0;
  // ρ_j per face (eq. 3.37); empty: 1 for every face. Finite and >= 0.
  std::span<const double> face_density;
  // Checked every 4,096 merges.
  const std::atomic<bool>* cancel = nullptr;
};

struct PlanarMerge {
  ClusterId kept;      // the smaller label of the two; the merged cluster keeps it
  ClusterId absorbed;  // the other label; no face has it afterwards
  double angle_degrees = 0;
};

struct PlanarMergingResult {
  // One label per face. Each is the smallest input label of the clusters merged into it,
  // so clusters that took part in no merge keep their labels.
  std::vector<ClusterId> labels;
  uint32_t input_clusters = 0;   // distinct input labels
  uint32_t output_clusters = 0;  // distinct output labels
  // In the order made; input_clusters - output_clusters entries.
  std::vector<PlanarMerge> merges;
};

// Merges as the header says. `labels` holds one label per face (any values but
// ClusterId::Invalid(); a cluster need not be edge-connected). A cluster whose normal sum
// is zero (a closed surface, or only zero-area faces) has no representative normal and is
// never merged.
//
// O(F + E log E) for F faces and E cluster adjacencies.
//
// Errors: ValidateMesh's INVALID_ARGUMENT; INVALID_ARGUMENT naming 'labels' (not one per
// face, or an invalid label), 'max_angle_degrees' (outside [0, 180] or NaN) or
// 'face_density' (not one per face, negative or not finite); CANCELLED.
absl::StatusOr<PlanarMergingResult> MergePlanarClusters(const TriangleMesh& mesh,
                                                        std::span<const ClusterId> labels,
                                                        const PlanarMergingOptions& options);

}  // namespace mlclust

#endif  // MLCLUST_CORE_CLUSTER_PLANAR_MERGING_H_
