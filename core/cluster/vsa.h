// Variational Shape Approximation (VSA; Cohen-Steiner, Alliez, Desbrun 2004; dissertation
// Alg. 2.1-2.2) with the L2,1 metric: the baseline the planar energy's drivers are
// measured against, and the algorithm of CGAL's Surface_mesh_approximation package.
//
// A region i has a proxy N_i, the normalised area-weighted mean normal of its faces, and
// a face j costs A_j |n_j - N_i|^2 against it, so the total over all regions is the planar
// (L2,1) energy of core/energies.h (PlanarEnergy). VSA is Lloyd's algorithm on the faces:
// seed k regions, then alternate
//   (1) partition (Alg. 2.2): every region restarts from its seed face (the face with the
//       smallest cost against its proxy); faces are claimed by priority-queue flooding
//       across edges, cheapest (face, region) pair first, each pair costed against the
//       proxy of the region that reaches the face; and
//   (2) fitting: every proxy is refitted to its new region.
// Flooding across edges from one seed keeps every region edge-connected and non-empty.
#ifndef MLCLUST_CORE_CLUSTER_VSA_H_
#define MLCLUST_CORE_CLUSTER_VSA_H_

#include <atomic>
#include <cstdint>
#include <functional>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/base/ids.h"
#include "core/base/vec3.h"
#include "core/cluster/mesh_clustering.h"

namespace mlclust {

struct VsaOptions {
  // How the k seeds are placed before the Lloyd iterations; as CGAL's
  // Surface_mesh_approximation::Seeding_method. Every method first gives each connected
  // component one region (its whole component, CGAL's bootstrap), then:
  enum class Seeding {
    // the missing k - components seeds at distinct random faces at once, then
    // `inner_iterations` Lloyd iterations.
    kRandom,
    // one seed at a time at the costliest face of the region with the largest error, each
    // followed by `inner_iterations` Lloyd iterations: (k - components) x inner_iterations
    // iterations in all, slow for large k.
    kIncremental,
    // rounds that double the number of regions (the last round tops up to k): the round's
    // new seeds are spread over the regions in proportion to their error (CGAL's error
    // diffusion) and placed within a region farthest first (each at the face that the
    // region's proxy and its new seeds so far fit worst; CGAL takes the region's first
    // faces); each round is followed by `inner_iterations` Lloyd iterations. About
    // log2(k) rounds.
    kHierarchical,
  };
  Seeding seeding = Seeding::kHierarchical;
  // k: in [connected components, faces]. Exactly k regions come back.
  uint32_t clusters = 0;
  // Lloyd iterations after seeding (CGAL's run(N); 30 as in CGAL's examples). 0 returns
  // the seeding's partition.
  uint32_t iterations = 30;
  // Lloyd iterations after each seeding step (CGAL's number_of_relaxations, default 5).
  // With 0, the seeding still ends with one partition, so that its regions are connected.
  uint32_t inner_iterations = 5;
  // Random generator seed (kRandom only): same seed, same result on every platform.
  uint64_t seed = 1;
  // Early stop: > 0 stops the Lloyd iterations after the first one whose energy fell by
  // less than this fraction of the previous iteration's energy (a rise counts as no fall);
  // 1e-6 is a sensible value. 0 runs all `iterations`. Independently of this, the
  // iterations always stop at a fixed point (a partition equal to the previous one), since
  // every further iteration would repeat it exactly; on real meshes Lloyd mostly ends in a
  // cycle of nearly equal partitions instead, which only this option stops.
  double min_relative_decrease = 0;
  // Region teleportation (Cohen-Steiner et al. 2004; CGAL's teleport_proxies), tried when
  // the iterations stall: where they would stop as described above, or where an
  // iteration did not lower the energy at all (Lloyd can cycle between partitions of equal
  // energy). The two adjacent regions whose merge adds the least error are merged and the
  // freed region is reseeded at the costliest face of the region of the largest error,
  // provided the merge adds less than half that region's error; the iterations then go on
  // (within `iterations`). Tried again at a later stall only if the energy there is below
  // that at the last teleport. It gets Lloyd out of local minima such as two regions on
  // one side of a cube, where CGAL's run() stays.
  bool teleport = true;
  // Called after each Lloyd iteration (not the seeding's) with its number (1-based) and
  // the energy of that iteration's partition. Flooding is greedy, so this energy may rise
  // slightly from one iteration to the next; the result is the best partition seen.
  std::function<void(uint32_t iteration, double energy)> on_iteration;
  // Checked within every flood, every few thousand faces (core/base/cancel.h).
  const std::atomic<bool>* cancel = nullptr;
};

struct VsaResult {
  // One region id per face, 0..k-1; every region is edge-connected and non-empty.
  std::vector<ClusterId> labels;
  // The planar (L2,1) energy of `labels`: sum_j A_j |n_j - N_i|^2 with N_i refitted to the
  // final regions. Equals EnergyFromSums(PlanarEnergy, labels) up to rounding.
  double energy = 0;
  double initial_energy = 0;  // the energy of the seeding's partition
  // The seeding's partition (labels as above): what a run with iterations = 0 returns as
  // `labels`, so a caller that reports the seeding as a level of its own needs no second
  // run of the seeding.
  std::vector<ClusterId> initial_labels;
  // Per region: the proxy (unit normal) fitted to it and its seed face (the face of the
  // smallest cost against that proxy, where the next partition would start).
  std::vector<Vec3> proxies;
  std::vector<FaceId> seeds;
  uint32_t iterations = 0;          // Lloyd iterations run after seeding
  uint32_t best_iteration = 0;      // the iteration whose partition is returned (0: seeding)
  uint32_t seeding_iterations = 0;  // Lloyd iterations run while seeding
  uint32_t teleports = 0;           // region teleportations done
  // Stopped before `iterations` at a fixed point or by min_relative_decrease (with no
  // teleport left to try).
  bool converged = false;
};

// Runs VSA on `problem` (whose pointers must be set and match the mesh, as for the other
// drivers). Deterministic: the same mesh and options give the same labels on every run
// (ties in the flood go to the smaller face id, randomness comes from core/random.h).
// Single-threaded; O(faces log faces) per Lloyd iteration, no allocation per iteration.
// Unlike CGAL, which caps k at faces / 3, any k in [components, faces] is reached exactly. Returns
// the partition of the lowest energy among the seeding's and the Lloyd iterations'.
// INVALID_ARGUMENT, naming the option, when problem.energy is not the planar energy ('energy'), or
// when k = 0, k > faces or k < the number of connected components
// ('clusters'); or ValidateMeshProblem's error. CANCELLED if options.cancel was set.
absl::StatusOr<VsaResult> RunVsa(const MeshProblem& problem, const VsaOptions& options);

// "random", "incremental", "hierarchical".
absl::StatusOr<VsaOptions::Seeding> ParseVsaSeeding(absl::string_view name);
const char* VsaSeedingName(VsaOptions::Seeding seeding);

}  // namespace mlclust

#endif  // MLCLUST_CORE_CLUSTER_VSA_H_
