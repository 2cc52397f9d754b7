// Meshlet-sized patches, ours: one level of many small connected clusters, fast.
//
// The dissertation's single-level route (chapter 3) is seeds, growth, then optimisation to
// convergence (EMLO, Alg. 3.3; or BB, Alg. 5.1). For thousands of small patches (a GPU
// meshlet holds about 124 triangles: K = faces / 124) most of that time goes into the
// l-neighbourhood seeding (Alg. 3.1, repeated BFS) and into the long tail of sweeps that
// each move a handful of faces. This route keeps the three steps and makes each cheap:
//
//   1. spread seeds    faces in Morton (Z-order) order of their centroids, per connected
//                      component, cut into K runs of equal face count; each run's middle
//                      face is a seed (every component gets one at least, the rest by
//                      face count)
//   2. growth          energy-free (l. 671, 1219) or the energy-ordered flood (Alg. 2.2),
//                      as GrowClustersFromSeeds does: every cluster connected
//   3. BB sweeps       a bounded number of boundary-based sweeps (Alg. 5.1: proxies fixed
//                      per sweep, every boundary face decides alone, in parallel, by
//                      boundary_based::DecideBoundaryMove) with the ring test of the
//                      connectivity guard; the moves apply in face order, each valid against
//                      the labels as they are by then (so neighbouring faces may move in one
//                      sweep, where BB's conflict rule defers one of them): no patch splits,
//                      and for the CVD energies no sweep raises the energy
//
// with, by default, one Lloyd step on the seeds between 2 and 3 (each seed moves to its
// cluster's face nearest the cluster's centroid, and all grow again). The defaults (6 sweeps,
// 1 Lloyd step) were chosen on bunny00, armadillo and armadillo_1m at K = faces / 124 to
// take less time than meshoptimizer's meshopt_buildMeshlets (BENCHMARKS.md, "Meshlet-sized
// patches"). The result is one partition of exactly K connected clusters.
#ifndef MLCLUST_CORE_CLUSTER_PATCHES_H_
#define MLCLUST_CORE_CLUSTER_PATCHES_H_

#include <atomic>
#include <cstdint>
#include <vector>

#include "absl/status/statusor.h"
#include "core/base/ids.h"
#include "core/cluster/mesh_clustering.h"

namespace mlclust {

// Step 1 alone: `clusters` distinct seed faces, at least one in every edge-connected
// component, the others shared among components by their face counts; within a component
// the faces in Morton order of their centroids (10 bits per axis of the mesh's bounding box,
// ties by face id) are cut into runs of equal length and each run's middle face is its
// seed. Deterministic (no random numbers). Seeds are listed component by component, in
// Morton order within one. INVALID_ARGUMENT if clusters is 0, above the face count or
// below the number of components; CANCELLED if `cancel` (may be null) was set.
absl::StatusOr<std::vector<FaceId>> SpreadSeeds(const MeshProblem& problem, uint32_t clusters,
                                                const std::atomic<bool>* cancel = nullptr);

struct PatchOptions {
  uint32_t clusters = 0;  // K, in [connected components, faces]
  // How the seeds grow (SeedOptions::Growth); energy-free by default: a BFS, the fastest,
  // and the sweeps then fit the patches to the energy.
  SeedOptions::Growth growth = SeedOptions::Growth::kEnergyFree;
  // Ours: growth kRounds on a device (SeedOptions::device_rounds); empty: the CPU.
  SeedOptions::DeviceGrowth device_rounds;
  // Lloyd steps on the seeds before the sweeps: every seed moves to its cluster's face
  // nearest the cluster's centroid and all grow again (ours).
  uint32_t reseeds = 1;
  // BB sweeps at most after growth (0: the grown seeds are the result). BB stops earlier
  // when nothing moves.
  uint32_t sweeps = 6;
  int threads = 0;  // BB's worker threads, 0 = all cores
  // Which connectivity check BB asks (kOff lets patches split: for experiments only).
  ConnectivityGuardKind guard = ConnectivityGuardKind::kRingTest;
  // Checked between the steps and inside each (core/base/cancel.h).
  const std::atomic<bool>* cancel = nullptr;
};

struct PatchResult {
  std::vector<ClusterId> initial_labels;  // the grown seeds, clusters 0..K-1
  std::vector<ClusterId> labels;          // after the sweeps, the same cluster ids
  double initial_energy = 0;
  double energy = 0;
  uint32_t sweeps = 0;  // BB sweeps run
  uint64_t moves = 0;
};

// Steps 1-3 (see the top of this file) with the problem's energy. INVALID_ARGUMENT as
// SpreadSeeds says or for a problem ValidateMeshProblem refuses, or threads < 0;
// CANCELLED if options.cancel was set.
absl::StatusOr<PatchResult> BuildPatches(const MeshProblem& problem, const PatchOptions& options);

}  // namespace mlclust

#endif  // MLCLUST_CORE_CLUSTER_PATCHES_H_
