// PML (Alg. 5.3) on the GPU for meshes with the CVD energy: the levels of merges, with
// every cluster's data kept on the GPU across levels; only the level's triplets and a few
// scalars per level come back (and, where the pair rule or the lowest level needs them,
// the level's pairs and their costs).
//
// One level (PmlLevelsGpu::Level), passes named for errors and MLCLUST_GPU_FAIL_PASS:
//   "pml odes"     every cluster's optimal dual edge (ODE, Def. 4.2) over the directed
//                  cluster edges: the minimum merge cost (eq. 4.3), equal costs to the
//                  larger id (CheaperDualEdge of core/cluster/detail/ode_heap.h), exact in
//                  fp64 through three 32-bit atomic passes (pml_ode.glsl); then the mutual
//                  pairs (pml_pairs.glsl, Alg. 5.8)
//   "pml collapse" the selected pairs merge (pml_merge.glsl): sums added, the larger
//                  cluster keeps its id (the CPU engine's KeepAndGone), the energy change
//   "pml triplets" stream compaction in face order (pml_compact.glsl): the faces whose
//                  cluster merged away become triplets (face, new, old) and are
//                  relabelled; the directed cluster edges are relabelled and those inside
//                  one cluster dropped
// The merge costs and energies are computed in the CPU's operation order with `precise`
// (no fused multiply-add), so on IEEE fp64 hardware the levels are the CPU engine's
// (core/cluster/multilevel.cc, optimizer none, parallel) exactly; the energy is the sum of
// the same per-cluster changes (in another order, compensated).
//
// Cluster adjacency: the directed face edges (f, g) across an edge of the mesh,
// relabelled to (cluster of f, cluster of g) each level and kept where the clusters
// differ — not deduplicated: a cluster pair appears once per face edge on their common
// boundary, so a level's ODE passes cost O(boundary face edges). At most 3 per face.
//
// Memory (PmlLevelsMemoryBound), bytes per face: 40 (sums) + 12 (size, label, remap) + 12
// (ODE key and partner) + 12 (triplets) + 72 (two edge lists and the edge keys, 8 bytes
// each per directed edge, at most 3 per face) + 18 (pairs: ids, values and flag, 36 bytes,
// at most one per two faces) + the compaction's counts (1/8): about 166 bytes per face,
// 166 MB for 10^6 faces. Each buffer must fit one storage buffer (RESOURCE_EXHAUSTED).
//
// Alg. 5.7 (PML with minimizeEnergy() after each collapse step; ours in how it splits the
// work, gpu/stages/multilevel_gpu.h drives it): EnableBoundaryOptimisation adds what BB
// sweeps (Alg. 5.4/5.5) need on the GPU, and three more passes:
//   "pml bb decide" every cluster's proxy from its sums (pml_bb.glsl, CvdEnergy::FitProxy
//                   in the CPU's order; only after a level's merges, since "pml bb apply"
//                   fits the changed clusters' again), then bb_decide.glsl
//                   (gpu/kernels/bb_decide.h, DecideBoundaryMove's rule) over every face against
//                   them, on the PML's own labels; only the proposals come back (8 bytes each)
//   "pml bb apply"  the moves the host accepted (the CPU's ResolveConflicts and
//                   ApplyMoves): the moved faces' labels and the changed clusters' sizes
//                   and sums written into the PML's buffers (scatter, pml_bb.glsl), and
//                   those clusters' proxies fitted again
//   "pml bb edges"  after a level with moves: the directed cluster edges rebuilt from
//                   every directed face edge and the labels (pml_compact.glsl, kind 2),
//                   since a move can turn an inner face edge into a boundary one
// Alg. 5.6 (ML: one collapse per step, then minimizeEnergy(); gpu/stages/multilevel_gpu.h
// drives it with the BB passes above): Step is a level of one merge, "pml odes" without
// the mutual pairs (every cluster's ODE only; nothing read back), then
//   "ml min ode"   findMinDE(): the cheapest ODE of all clusters (ml_min_ode.glsl, one work
//                  group), in the CPU engine's queue order (cost, then the fewer faces with
//                  ties_to_fewest_faces, then the smaller id; HC's tree of minima orders
//                  the same), its pair read back (8 bytes)
// and that pair through "pml collapse" (the merge pass alone: no pair selection) and
// "pml triplets". Each step costs O(faces + face edges) on the GPU (as the dissertation's
// findMinDE over every boundary face), so the steps of a whole hierarchy O(faces^2): HC's
// incremental steps (hc_levels.h) cannot take BB's moves, which re-shape clusters anywhere.
// Memory for BB (PmlBoundaryMemoryBound), bytes per face: 24 (the face edges, kept) + 12
// (neighbours) + 32 (point and mass) + 32 (proxies) + 8 (proposals) = 108, plus 56 per
// change slot (kPmlBbChangeChunk at most: label change 8, cluster id and size 8, sums
// 40): about 108 MB for 10^6 faces, with PmlLevelsMemoryBound's 166 about 274.
#ifndef MLCLUST_GPU_KERNELS_PML_LEVELS_H_
#define MLCLUST_GPU_KERNELS_PML_LEVELS_H_

#include <array>
#include <cstdint>
#include <functional>
#include <span>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "core/cluster/detail/pml_pairs.h"
#include "core/energy/energies.h"
#include "core/mesh/mesh.h"
#include "gpu/context/compute.h"
#include "gpu/context/gl_context.h"
#include "gpu/kernels/bb_decide.h"
#include "gpu/kernels/pml_pair_selection.h"

namespace mlclust::gpu {

// One level's result (pml_pair_selection.h); the triplets in face order.
using PmlLevelGpu = GpuPmlLevel;

// The bytes PmlLevelsGpu allocates for `num_faces` faces and `num_edges` directed face
// edges (at most 3 * num_faces).
uint64_t PmlLevelsMemoryBound(uint64_t num_faces, uint64_t num_edges);

// Changes (moved faces, changed clusters) one "pml bb apply" dispatch writes at most; more
// go in several.
inline constexpr uint32_t kPmlBbChangeChunk = 65536;

// The bytes EnableBoundaryOptimisation adds, for `num_faces` faces and `num_edges`
// directed face edges.
uint64_t PmlBoundaryMemoryBound(uint64_t num_faces, uint64_t num_edges);

// A face to move: (face, cluster).
using PmlFaceMove = std::array<uint32_t, 2>;
// A cluster's new size and sums after moves.
struct PmlClusterChange {
  uint32_t cluster = 0;
  uint32_t size = 0;
  CvdSums sums;
};

class PmlLevelsGpu {
 public:
  // Uploads one cluster per face (face_sums[f], CvdEnergy::face_sums) and the directed
  // face edges of `adjacency`. INVALID_ARGUMENT for a size mismatch, a neighbour out of
  // range or more than kMaxMeshElements / 6 faces; RESOURCE_EXHAUSTED if a buffer exceeds
  // context.max_storage_buffer_bytes() or GPU memory runs out; INTERNAL on GL errors.
  static absl::StatusOr<PmlLevelsGpu> Create(GlContext& context, std::span<const CvdSums> face_sums,
                                             const FaceAdjacency& adjacency);

  // One PML level at `clusters` clusters: the mutual pairs, of them those `rule` keeps
  // (SelectPmlPairs), and of those at most clusters - lowest (the cheapest, ties by pair,
  // as the CPU engine), collapsed; false (and nothing changed) where there is no mutual
  // pair. Errors name the pass.
  absl::StatusOr<bool> Level(PmlPairRule rule, uint32_t clusters, uint32_t lowest,
                             PmlLevelGpu& level);

  // One ML step (Alg. 5.6) at the current clusters: the cheapest ODE (ties as the CPU
  // engine's queue, `ties_to_fewest_faces` as MultilevelOptions) collapsed, into `level`
  // (merged 1, its triplets and energy change; mutual_pairs 0: not searched); false (and nothing
  // changed) where no cluster has an ODE left. Errors name the pass ("ml min ode" for the choice).
  absl::StatusOr<bool> Step(bool ties_to_fewest_faces, PmlLevelGpu& level);

  // The current labels (downloaded; for tests).
  absl::StatusOr<std::vector<uint32_t>> Labels();

  // ---- Alg. 5.7: BB sweeps between the levels (see the top of this file) ---------------

  // Uploads what the BB passes need: `adjacency` must be Create's, `faces` one point and
  // mass per face (ProxyPointForm<CvdEnergy>::Face). Errors as Create, named "pml bb
  // decide".
  absl::Status EnableBoundaryOptimisation(const FaceAdjacency& adjacency,
                                          std::span<const PointAndWeight> faces);

  // One decide over every face against proxies fitted to the clusters' current sums:
  // `proposals` becomes the faces that want to move and where (each face at most once, in
  // no particular order). FAILED_PRECONDITION before EnableBoundaryOptimisation; errors
  // name "pml bb decide".
  absl::Status Decide(std::vector<PmlFaceMove>& proposals);

  // Writes moves made on the host into the GPU's state: labels[face] = cluster for each
  // move, and each changed cluster's size and sums (which the host computed). Errors name
  // "pml bb apply".
  absl::Status ApplyMoves(std::span<const PmlFaceMove> moves,
                          std::span<const PmlClusterChange> clusters);

  // After moves: the directed cluster edges again from every directed face edge and the
  // labels. Errors name "pml bb edges".
  absl::Status RebuildEdges();

 private:
  enum Binding : uint32_t {
    kSums,
    kSizes,
    kLabels,
    kRemap,
    kEdgesIn,
    kEdgesOut,
    kEdgeKeys,
    kOdes,
    kPairIds,
    kPairValues,
    kPairSelected,
    kChunkCount,
    kGroupTotal,
    kCounters,
    kTriplets,
    kBindings
  };
  struct Programs {
    uint32_t ode = 0, pairs = 0, merge = 0, compact = 0;
    uint32_t min_ode = 0;  // Step's, compiled at its first call
  };
  // EnableBoundaryOptimisation's buffers (bindings are set per pass).
  enum BoundaryBuffer : uint32_t {
    kFaceEdges,
    kNeighbours,
    kFacePoints,
    kProxies,
    kProposals,
    kProposalCount,
    kLabelChanges,
    kClusterChanges,
    kClusterSums,
    kBoundaryBuffers
  };

  PmlLevelsGpu(GlContext& context, uint32_t num_faces, uint32_t num_edges, Programs programs,
               std::vector<StorageBuffer> buffers)
      : context_(&context),
        num_faces_(num_faces),
        num_edges_(num_edges),
        programs_(programs),
        buffers_(std::move(buffers)) {}

  void BindAll();
  // pml_bb.glsl's bindings: sums, sizes, labels, proxies, the label changes, the cluster
  // changes and their sums.
  void BindBbBuffers();
  absl::StatusOr<uint32_t> FindPairs();
  // A level's start ("pml odes"): every ODE and the mutual pairs (returned).
  absl::StatusOr<uint32_t> StartLevel(PmlLevelGpu& level);
  // A level's end: `collapse` ("pml collapse"), then the triplets of `pairs` pairs.
  absl::Status FinishLevel(const std::function<absl::Status()>& collapse, uint32_t pairs,
                           PmlLevelGpu& level);
  absl::Status Collapse(PmlPairRule rule, uint32_t clusters, uint32_t lowest, uint32_t pairs,
                        PmlLevelGpu& level);
  absl::Status Compact(uint32_t kind, uint32_t count, uint32_t slot);
  absl::Status Extract(uint32_t pairs, PmlLevelGpu& level);

  GlContext* context_;
  uint32_t num_faces_;
  uint32_t num_edges_;  // directed cluster edges in kEdgesIn
  Programs programs_;
  std::vector<StorageBuffer> buffers_;
  // BB (EnableBoundaryOptimisation): its buffers, the directed face edges and programs.
  std::vector<StorageBuffer> bb_buffers_;
  uint32_t num_face_edges_ = 0;
  uint32_t bb_program_ = 0;
  // Whether the proxies on the GPU are those of the current sums (Level's merges change
  // sums; ApplyMoves fits the changed clusters' proxies again).
  bool proxies_current_ = false;
  std::vector<uint32_t> change_words_;
  std::vector<double> change_sums_;
};

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_KERNELS_PML_LEVELS_H_
