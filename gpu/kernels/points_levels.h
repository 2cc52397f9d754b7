// PML (Alg. 5.3) for points on the GPU (section 6.4.3): the levels of merges over the
// local neighbours (section 6.1), with every cluster's data kept on the GPU across levels;
// only the level's triplets and a few scalars per level come back (and, where the pair
// rule or the lowest level needs them, the level's pairs and their costs).
//
// One level (PointLevelsGpu::Level), passes named for errors and MLCLUST_GPU_FAIL_PASS:
//   "points odes"       every cluster's optimal dual edge over its neighbours and the
//                       clusters listing it (points_ode.glsl: exact fp64 minimum of the
//                       Ward cost in three 32-bit atomic passes, equal costs to the
//                       larger id), then the mutual pairs (points_pairs.glsl)
//   "points collapse"   the selected pairs merge (points_merge.glsl): sums added, the
//                       larger cluster keeps its id, the energy change
//   "points triplets"   stream compaction in point order (pml_compact.glsl, shared with
//                       the meshes' PML): the points whose cluster merged away become
//                       triplets (point, new, old) and are relabelled
//   "points neighbours" every live cluster's local neighbours (eq. 6.1) from the
//                       second-order candidates through the merges (points_refresh.glsl)
// HC and ML (one merge per step: StartSteps, then StepMerge and StepRefresh per step; the
// CPU engine's SequentialMerge and PointSpace::UpdateOdes), passes:
//   "points hc odes"     the ODEs afresh (points_ode.glsl, as above; after a step only
//                        over the edges of the clusters the CPU recomputes and of those
//                        whose stored partner is gone), then the stored ODEs (the CPU's
//                        queue) take those the CPU recomputes (points_hc.glsl)
//   "points hc select"   the cheapest stored ODE (ml_min_ode.glsl: cost, then id), a
//                        gone partner's ODE recomputed and the choice repeated
//                        (points_hc.glsl); then "points collapse" as above for the one
//                        pair (the caller's triplets, relabelled by "points update")
//   "points hc neighbours" the clusters the CPU refreshes, in its order of groups (within
//                        a group by id; the CPU: its reverse lists' order), refreshed one
//                        after the other as the CPU does (points_hc.glsl)
// Merge costs, sums, centroids and distances are computed in the CPU's operation order
// with `precise`, so a level's ODEs, pairs and merges are the CPU engine's wherever the
// neighbour tables agree (always at the first level; see points_multilevel_gpu.h).
//
// Memory (PointLevelsMemoryBound), bytes: per point 4 (label) + 12 (triplet) + 1/8
// (compaction counts); per cluster of the start 4 (size) + 8d (centroid) + 8(d + 1)
// (sums) + 4 (remap) + 16d (two neighbour tables) + 12 (ODE) + 16d (ODE keys) + 8
// (partner) + 18 (pairs: 36 bytes, at most one per two clusters): for 10^6 3-D points
// from 1.25 * 10^5 voxels, 16 MB + 18 MB. With LN k-means (Update's staging, grown on
// demand up to every point and cluster at once) 8 more per point and 8 + 8(2d + 1) more
// per cluster. For HC and ML 12 (stored ODEs) + 20 (a step's lists) + 8d (its rows) more
// per cluster.
#ifndef MLCLUST_GPU_KERNELS_POINTS_LEVELS_H_
#define MLCLUST_GPU_KERNELS_POINTS_LEVELS_H_

#include <cstdint>
#include <initializer_list>
#include <span>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "core/cluster/detail/pml_pairs.h"
#include "gpu/context/compute.h"
#include "gpu/context/gl_context.h"
#include "gpu/kernels/ln_kmeans.h"
#include "gpu/kernels/pml_pair_selection.h"

namespace mlclust::gpu {

// Mesa's software renderers stop every loop of a shader invocation, without a word, once
// 65,535 iterations have run in it (all loops together; gpu/kernels/hc_levels.cc): the
// iterations one invocation of the point levels may plan for there. The stage refuses runs
// whose one refresh could pass it (points_multilevel_gpu.cc); HC's and ML's sequential
// refresh dispatches at most this many iterations' worth of clusters at a time.
inline constexpr uint64_t kPointsSoftwareLoopBudget = 60000;

// One level's result (pml_pair_selection.h); the triplets in point order.
using PointLevelGpu = GpuPmlLevel;

// The clusters of the start, as the GPU levels take them.
struct PointLevelsStart {
  uint32_t dims = 0;
  std::span<const uint32_t> labels;      // per point (any order the caller reports in)
  std::span<const uint32_t> counts;      // per cluster (k)
  std::span<const double> sums;          // k x (d + 1): coordinate sums, then square sum
  std::span<const double> centroids;     // k x d
  std::span<const uint32_t> neighbours;  // k x 2d, 0xFFFFFFFF where none
};

// The bytes PointLevelsGpu allocates for m points, k clusters, d dimensions.
uint64_t PointLevelsMemoryBound(uint64_t m, uint64_t k, uint32_t d);

class PointLevelsGpu {
 public:
  // Uploads the start. INVALID_ARGUMENT for sizes that do not agree or a label or
  // neighbour out of range; RESOURCE_EXHAUSTED if a buffer exceeds
  // context.max_storage_buffer_bytes() or GPU memory runs out; INTERNAL on GL errors.
  static absl::StatusOr<PointLevelsGpu> Create(GlContext& context, const PointLevelsStart& start);

  // One PML level at `clusters` clusters: the mutual pairs, of them those `rule` keeps
  // (SelectPmlPairs), and of those at most clusters - lowest (the cheapest, ties by pair,
  // as the CPU engine), collapsed, and the neighbours refreshed; false (and nothing
  // changed) where there is no mutual pair. Errors name the pass.
  absl::StatusOr<bool> Level(PmlPairRule rule, uint32_t clusters, uint32_t lowest,
                             PointLevelGpu& level);

  // Level in two parts, for LN k-means between them (gpu/stages/points_optimise_gpu.h):
  // MergeLevel is Level up to the triplets (the neighbour table is still the one before the
  // level; false: no mutual pair, nothing changed), RefreshNeighbours its last pass.
  absl::StatusOr<bool> MergeLevel(PmlPairRule rule, uint32_t clusters, uint32_t lowest,
                                  PointLevelGpu& level);
  absl::Status RefreshNeighbours();

  // The resident labels, centroids, neighbour table and counts, for LN k-means' assign
  // (LnKmeansKernel::AssignResident); valid until the next call that changes this object.
  LnKmeansResidentClusters Resident() const;

  // Writes moves made on the host into the resident state (pass "points update"): for
  // each of `clusters` its count, its d + 1 sums and its d centroid values (`values`,
  // 2d + 1 per cluster), and for each of `points` its label. INVALID_ARGUMENT for sizes
  // that do not agree or ids out of range. The staging buffers grow to the largest update
  // (at most 8 + 8(2d + 1) bytes per cluster and 8 per point: PointLevelsMemoryBound).
  absl::Status Update(std::span<const uint32_t> clusters, std::span<const uint32_t> counts,
                      std::span<const double> values, std::span<const uint32_t> points,
                      std::span<const uint32_t> labels);

  // Every live cluster's neighbours: the nearest live cluster in each subspace (the CPU's
  // ConnectWhenStuck; O(k^2), for few clusters). Pass "points neighbours".
  absl::Status LinkAll();

  // HC and ML (one merge per step). StartSteps: every stored ODE afresh (at the start,
  // and after LinkAll as the CPU's ConnectWhenStuck). StepMerge: the cheapest stored ODE's
  // two clusters merged (the larger keeps its id, the smaller id on equal sizes: the CPU
  // engine's KeepAndGone), `keep`, `gone` and the merged `size` as the GPU has them,
  // level.merged = 1 and level.energy_change set; false (nothing changed) where no cluster
  // has an ODE. The triplets (the gone cluster's points)
  // and the relabelling (Update) are the caller's: a search of the points for them would
  // cost every point per step (m k0 in all). StepRefresh: after the step (and LN k-means), the
  // neighbours of the clusters the CPU refreshes and the ODEs it recomputes; `touched`:
  // the level's touched clusters in the CPU recorder's order (keep and gone first); with
  // `rows`, the clusters whose rows changed (the refreshed ones, then the gone one: n + 1
  // ids) and then their rows (2d each). Errors name the pass.
  absl::Status StartSteps();
  absl::StatusOr<bool> StepMerge(PointLevelGpu& level, uint32_t& keep, uint32_t& gone,
                                 uint32_t& size);
  absl::Status StepRefresh(uint32_t keep, uint32_t gone, std::span<const uint32_t> touched,
                           std::vector<uint32_t>* rows = nullptr);

  // The current labels and neighbour table, downloaded (pass "points read-back").
  absl::StatusOr<std::vector<uint32_t>> Labels();
  absl::StatusOr<std::vector<uint32_t>> Neighbours();

 private:
  enum Binding : uint32_t {
    kCounts,
    kCentroids,
    kLabels,
    kRemap,
    kNeighboursIn,
    kNeighboursOut,
    kSums,
    kOdes,
    kPairIds,
    kPairValues,
    kPairSelected,
    kChunkCount,
    kGroupTotal,
    kCounters,
    kTriplets,
    kPartner,
    kEdgeKeys,
    kStoredOdes,
    kHcWork,
    kBindings
  };
  struct Programs {
    uint32_t ode = 0, pairs = 0, merge = 0, compact = 0, refresh = 0, update = 0, hc = 0,
             min_ode = 0;
  };

  PointLevelsGpu(GlContext& context, uint32_t m, uint32_t k, uint32_t d, Programs programs,
                 std::vector<StorageBuffer> buffers)
      : context_(&context),
        m_(m),
        k_(k),
        d_(d),
        programs_(programs),
        buffers_(std::move(buffers)) {}

  void BindAll();
  absl::StatusOr<uint32_t> FindPairs();
  absl::Status Collapse(PmlPairRule rule, uint32_t clusters, uint32_t lowest, uint32_t pairs,
                        PointLevelGpu& level);
  absl::Status Extract(uint32_t pairs, PointLevelGpu& level);
  absl::Status Refresh(bool link_all);
  // points_hc.glsl's phase over `invocations` (uniforms 0, 1 and those in `uniforms`:
  // location, value).
  absl::Status HcPhase(uint32_t phase, uint64_t invocations,
                       std::initializer_list<std::pair<uint32_t, uint32_t>> uniforms = {});
  // Every fresh ODE, then the stored ones := the fresh ones, all or those flagged.
  absl::Status CommitOdes(bool all);
  // Buffer `binding`'s first out.size() uints into `out` (pass "points read-back").
  absl::Status ReadBack(uint32_t binding, std::span<uint32_t> out);

  GlContext* context_;
  uint32_t m_, k_, d_;
  uint32_t level_ = 0;
  Programs programs_;
  std::vector<StorageBuffer> buffers_;
  std::vector<StorageBuffer> staging_;  // Update's ids and values, grown on demand
};

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_KERNELS_POINTS_LEVELS_H_
