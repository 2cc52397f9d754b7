// Single-level mesh clustering: initial clusters, EMLO and boundary-based optimisation.
//
// Every function takes the mesh, its adjacency and face measures (a MeshProblem), an energy
// (MeshEnergyOptions: any energy in core/energies.h) and an options struct, and returns an
// absl::Status or result. Labels are one cluster id per face; functions that produce
// labels number clusters 0..k-1.
#ifndef MLCLUST_CORE_CLUSTER_MESH_CLUSTERING_H_
#define MLCLUST_CORE_CLUSTER_MESH_CLUSTERING_H_

#include <atomic>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "absl/status/statusor.h"
#include "core/base/ids.h"
#include "core/energy/energies.h"
#include "core/mesh/connectivity_guard.h"
#include "core/mesh/face_measures.h"
#include "core/mesh/mesh.h"
#include "core/mesh/polygons.h"
#include "core/mesh/prepared_mesh.h"

namespace mlclust {

// The data every mesh algorithm needs. The pointers must outlive the call; the mesh must
// have passed ValidateMesh, and adjacency and measures must be the mesh's.
struct MeshProblem {
  const TriangleMesh* mesh = nullptr;
  const FaceAdjacency* adjacency = nullptr;
  const FaceMeasures* measures = nullptr;
  MeshEnergyOptions energy;
  // Ours, issue 13: the input's polygons (core/mesh/polygons.h; from MakeMeshPolygons on
  // this mesh's adjacency), or null. With polygons every function here and RunMultilevel
  // (multilevel.h) treat a polygon as one element: its triangles are always in one
  // cluster, a polygon's sums are its triangles' sums added, polygons neighbour across
  // triangle edges and the ring test guards polygon moves (core/mesh/polygons.h).
  // Labels stay one per face; labels passed in must keep each polygon's triangles in one
  // cluster (INVALID_ARGUMENT naming the polygon otherwise). InitialClusters' Alg. 3.1
  // runs on the triangles and moves each seed to its polygon (ours: the polygons' dual
  // graph is too coarse for it; BENCHMARKS.md). Alg. 3.2's vertex
  // boundary-edge count guard and SeedOptions::add_seeds are per triangle and refused
  // with polygons.
  const MeshPolygons* polygons = nullptr;
};

// The problem of a prepared mesh (core/mesh/prepared_mesh.h, core/io/prepare_mesh.h) with
// the given energy; `prepared` must outlive it.
MeshProblem MakeMeshProblem(const PreparedMesh& prepared, const MeshEnergyOptions& energy = {});

// The preconditions every mesh algorithm checks first: mesh, adjacency and measures all
// set, adjacency and measures of the mesh's face count, and energy options that
// ValidateMeshEnergyOptions accepts. INVALID_ARGUMENT saying which fails. (That the mesh
// passed ValidateMesh is the caller's promise: PrepareMesh keeps it.)
absl::Status ValidateMeshProblem(const MeshProblem& problem);

struct SeedOptions {
  enum class Method {
    kRandom,          // k distinct faces, at least one per connected component
    kLNeighbourhood,  // Alg. 3.1: faces whose l-neighbourhoods do not overlap, reduced to k
  };
  Method method = Method::kLNeighbourhood;
  uint32_t clusters = 0;  // k, in [1, faces] and >= the number of connected components
  // l for kLNeighbourhood: the seeds' neighbourhoods of l edge-steps do not overlap.
  // 0 picks the largest l that still yields at least k seeds.
  uint32_t level = 0;
  uint64_t seed = 1;  // random generator seed: same seed, same result on every platform
  // Checked between steps and every few thousand faces of each (core/base/cancel.h).
  const std::atomic<bool>* cancel = nullptr;

  // How seeds grow into clusters.
  enum class Growth {
    // Alg. 2.2's flood: free faces join the reaching cluster whose proxy fits them best,
    // cheapest first (the CVD family by distance to the seed's centroid). The default.
    kEnergyOrdered,
    // The "initial cluster grow" of l. 671 and l. 1219: no energy; clusters in turn, in
    // seed order, each take every free face across their boundary, until none is free.
    kEnergyFree,
    // Section 5.2's growth on the GPU (Fig. 5.9, l. 2172-2185): no energy; in rounds, every
    // free face with an edge-neighbour in a cluster joins the neighbouring cluster with
    // the smallest id, all faces of a round reading the labels before the round (Jacobi),
    // until a round assigns nothing. The same on the CPU and the GPU (device_rounds), and
    // the same partition as kEnergyFree (whose clusters in turn take the faces across
    // their last round's faces: the first to reach a face has the smallest id); the CPU
    // grows it as kEnergyFree. Its own value for the device: the GPU runs this rule.
    kRounds,
  };
  Growth growth = Growth::kEnergyOrdered;

  // Ours: kRounds on a device. Grows distinct in-range seed faces (cluster i from
  // seeds[i]) over the triangles' adjacency exactly as the CPU's kRounds does, free faces
  // left as 0xFFFFFFFF; its error (CANCELLED once `cancel` is seen set) is the caller's.
  // Empty: the CPU grows. Not used with polygons (MeshProblem::polygons): those grow on
  // the CPU.
  using DeviceGrowth = std::function<absl::StatusOr<std::vector<uint32_t>>(
      const FaceAdjacency& adjacency, std::span<const uint32_t> seeds,
      const std::atomic<bool>* cancel)>;
  DeviceGrowth device_rounds;

  // kLNeighbourhood with more seeds than k: how the three clusters meeting at the vertex
  // with the smallest summed area become one (l. 849), until k are left.
  enum class Reduction {
    // Ours, the default: the three grown regions are merged as they are.
    kMergeRegions,
    // l. 849: the merged cluster's seed moves to the three clusters' common vertex (a face
    // around it), and when k are left every seed grows again from scratch.
    kReseedAndRegrow,
  };
  Reduction reduction = Reduction::kMergeRegions;

  // kLNeighbourhood with fewer seeds than k (an l given too large): instead of refusing,
  // l. 849's seed-adding variant: grow, add seeds at the common vertices of three
  // neighbouring clusters with the largest summed area (one per cluster per round), grow
  // again, until k. Where no vertex joins three clusters (fewer than 3 seeds on a
  // component), the face of the cluster with the most faces farthest (in edge steps) from
  // its seed.
  bool add_seeds = false;
};

// Seeds and grows them to a full partition of exactly `clusters` connected clusters.
// Growing is options.growth (by default the VSA-style flood of Alg. 2.2, with the chosen
// energy). With kLNeighbourhood the seeds' regions are reduced to exactly k by repeatedly
// merging the three clusters that meet at a vertex with the smallest summed area
// (section 3.1.5, l. 849; options.reduction says whether the merged regions are kept or
// re-seeded and regrown), the last step merging a pair if k differs in parity; with
// options.add_seeds an l that gives fewer than k seeds gets seeds added.
// INVALID_ARGUMENT names the option that is out of range (k < 1, k > faces, k < connected
// components, l too large for k without add_seeds); CANCELLED if options.cancel was set.
absl::StatusOr<std::vector<ClusterId>> InitialClusters(const MeshProblem& problem,
                                                       const SeedOptions& options);

// Grows distinct seed faces into a full partition, cluster i from seeds[i], as
// `growth` says; kRounds on the device where `device` (may be null) is set
// (SeedOptions::device_rounds; not with polygons). INVALID_ARGUMENT if a seed is out of
// range or repeated, or a connected component has no seed; CANCELLED if `cancel` (may be
// null) was set; the device's errors.
absl::StatusOr<std::vector<ClusterId>> GrowClustersFromSeeds(
    const MeshProblem& problem, std::span<const FaceId> seeds, SeedOptions::Growth growth,
    const std::atomic<bool>* cancel, const SeedOptions::DeviceGrowth* device = nullptr);

// OK, or INVALID_ARGUMENT naming the first seed that is out of range (>= num_faces) or
// repeated: GrowClustersFromSeeds' check of its seeds.
absl::Status CheckSeedFaces(size_t num_faces, std::span<const uint32_t> seeds);

// Alg. 3.1 alone: the seed faces for neighbourhood size `level`, in face order.
std::vector<FaceId> LNeighbourhoodSeeds(const FaceAdjacency& adjacency, uint32_t level);

struct OptimizeResult {
  double initial_energy = 0;
  double energy = 0;
  uint64_t moves = 0;
  uint32_t iterations = 0;  // BB sweeps; for EMLO the number of progress reports
  bool converged = true;    // false if a move or iteration cap stopped it
};

struct EmloOptions {
  // The connectivity guard (Alg. 3.2's purpose): no cluster splits or gains a hole.
  // False is the same as guard == kOff.
  bool connectivity_guard = true;
  // Which check (core/mesh/connectivity_guard.h): our ring test or Alg. 3.2's vertex
  // boundary-edge counts (kept up to date after every move).
  ConnectivityGuardKind guard = ConnectivityGuardKind::kRingTest;
  // Stop after this many moves (0: 1000 x faces, a safety net only).
  uint64_t max_moves = 0;
  // Called every `progress_moves` moves and at the end with the total energy.
  std::function<void(uint64_t moves, double energy)> on_progress;
  uint64_t progress_moves = 10000;
  // Checked between set-up steps and every few thousand faces (core/base/cancel.h).
  const std::atomic<bool>* cancel = nullptr;
};

// EMLO (Alg. 3.3) from `labels` until no boundary move lowers the energy. `labels` is
// replaced by the result; clusters keep their ids (no cluster disappears).
// INVALID_ARGUMENT if labels.size() differs from the face count; CANCELLED (labels
// unchanged) if options.cancel was set.
absl::StatusOr<OptimizeResult> OptimizeEmlo(const MeshProblem& problem,
                                            std::vector<ClusterId>& labels,
                                            const EmloOptions& options = {});

struct BoundaryBasedOptions {
  uint32_t max_iterations = 200;
  int threads = 0;                 // 0: all cores
  bool connectivity_guard = true;  // false is the same as guard == kOff
  // Which check, as for EmloOptions::guard; asked against the sweep's starting state.
  ConnectivityGuardKind guard = ConnectivityGuardKind::kRingTest;
  // Called after each sweep with its number (1-based) and the total energy.
  std::function<void(uint32_t iteration, double energy)> on_iteration;
  // Checked before each stage of a sweep (core/base/cancel.h).
  const std::atomic<bool>* cancel = nullptr;
};

// Boundary-based optimisation (Alg. 5.1): proxies are fixed for a sweep; every boundary
// face decides on its own, in parallel, whether a neighbouring cluster's proxy fits it
// better; proposals the connectivity guard refuses are dropped, and of the remaining
// moves of faces that share a vertex only the one with the smaller id applies in the
// sweep (the other retries next sweep), so each move's connectivity check stays valid. A sweep that
// would raise the energy (possible for MWCVD, whose weights are not fitted) is undone and ends the
// run. Stops when nothing moves or after max_iterations. Clusters keep their ids, as for
// OptimizeEmlo. CANCELLED (labels unchanged) if options.cancel was set. Runs as the stages of
// core/cluster/boundary_based.h.
absl::StatusOr<OptimizeResult> OptimizeBoundaryBased(const MeshProblem& problem,
                                                     std::vector<ClusterId>& labels,
                                                     const BoundaryBasedOptions& options = {});

}  // namespace mlclust

#endif  // MLCLUST_CORE_CLUSTER_MESH_CLUSTERING_H_
