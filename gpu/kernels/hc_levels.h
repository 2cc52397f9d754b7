// HC (Alg. 2.3; Alg. 5.6 without the local optimisation: one collapse per step) on the
// GPU for meshes with the CVD energy, the data on the GPU throughout: the sums, every
// cluster's optimal dual edge (ODE, Def. 4.2), its faces and face edges as linked lists,
// and a tree of minima over the ODEs. The host only starts batches of steps and reads each
// batch's log back (per step the pair, its energy changes and the faces that moved).
//
// Passes, named for errors and MLCLUST_GPU_FAIL_PASS:
//   "hc odes"      at the start: every cluster's ODE through gpupml's kernel (pml_ode.glsl:
//                  exact fp64 minimum in three 32-bit atomic passes, equal costs to the
//                  larger id), then the tree level by level (hc_init.glsl)
//   "hc collapse"  a batch of steps in one work group (hc_steps.glsl): the root of the
//                  tree is the cheapest ODE (ties as the CPU engine's queue: cost, then the
//                  fewer faces, then the smaller id); the pair collapses (the larger
//                  cluster keeps its id, KeepAndGone); only the touched neighbourhood is
//                  recomputed: keep's ODE over its boundary edges (the edges now inside
//                  keep are unlinked on the way), each neighbour's ODE in full where it
//                  was keep or gone and otherwise against the edge to keep; then the tree
//                  nodes above the touched clusters. A step costs O(keep's boundary face
//                  edges + gone's faces + the neighbours' work + touched x 32 x tree levels),
//                  never O(faces)
//   "hc triplets"  the batch's log back: per step (keep, gone, energy changes) and gone's
//                  faces in the CPU engine's member order (its triplet order)
// The merge costs and energies are pml_cvd.glsl's (the CPU's operations, `precise`), so
// on IEEE fp64 hardware (llvmpipe, NVIDIA) the levels are the CPU engine's
// (core/cluster/multilevel.cc, optimizer none) exactly: the same pairs in the same order,
// the same triplets in the same order, and the energy summed from the same changes in the
// same order.
//
// Memory (HcLevelsMemoryBound), bytes per face: 40 (sums) + 32 (cluster record) + 8 (ODE
// cost) + 4 (label) + 4 (member list) + 4 (touched list) + 4 (log) + 12 (the start's ODE
// keys) + under 1 (tree); per directed face edge (at most 3 per face): 8 (faces) + 4
// (list) + 8 (the start's keys); plus 32 per step of a batch. About 169 bytes per face
// (169 MB for 10^6 faces). Each buffer must fit one storage buffer (RESOURCE_EXHAUSTED).
#ifndef MLCLUST_GPU_KERNELS_HC_LEVELS_H_
#define MLCLUST_GPU_KERNELS_HC_LEVELS_H_

#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "core/energy/energies.h"
#include "core/mesh/mesh.h"
#include "gpu/context/compute.h"
#include "gpu/context/gl_context.h"

namespace mlclust::gpu {

// Children per node of the tree of minima (hc_common.glsl's kFanout).
inline constexpr uint32_t kHcTreeFanout = 32;
// Invocations of the steps' work group (hc_steps.glsl), and on software renderers, where
// a group is one SIMD batch of a CPU thread and every barrier switches between batches.
inline constexpr uint32_t kHcStepGroup = 64;
inline constexpr uint32_t kHcSoftwareStepGroup = 8;
// Steps per batch (one dispatch) at most, unless HcLevelsGpu::Steps is told fewer.
inline constexpr uint32_t kHcMaxBatch = 4096;

// One step: `gone` merged into `keep`; its faces moved (in the CPU's order).
struct HcStepGpu {
  uint32_t keep = 0, gone = 0;
  uint32_t first = 0, count = 0;  // the faces: HcBatchGpu::faces[first, first + count)
  double keep_change = 0;         // E(keep after) - E(keep before)
  double gone_change = 0;         // 0 - E(gone before)
};
static_assert(sizeof(HcStepGpu) == 32);  // hc_steps.glsl's Step (std430)

struct HcBatchGpu {
  std::vector<HcStepGpu> steps;
  std::vector<uint32_t> faces;
};

// The bytes HcLevelsGpu allocates for `num_faces` faces and `num_edges` directed face
// edges (at most 3 * num_faces).
uint64_t HcLevelsMemoryBound(uint64_t num_faces, uint64_t num_edges);

class HcLevelsGpu {
 public:
  // Uploads one cluster per face (face_sums[f], CvdEnergy::face_sums) and the directed
  // face edges of `adjacency`, and finds every ODE and the tree ("hc odes"). Equal ODE
  // costs go first to the cluster with the fewer faces with `ties_to_fewest_faces`
  // (MultilevelOptions), then to the smaller id. INVALID_ARGUMENT for a size mismatch, a
  // neighbour out of range or 2^30 faces or more; RESOURCE_EXHAUSTED if a buffer exceeds
  // context.max_storage_buffer_bytes() or GPU memory runs out; INTERNAL on GL errors.
  // `step_group`: the steps' work group size, 0 for the renderer's (kHcStepGroup, or
  // kHcSoftwareStepGroup on software; tests run the hardware's on llvmpipe too).
  static absl::StatusOr<HcLevelsGpu> Create(GlContext& context, std::span<const CvdSums> face_sums,
                                            const FaceAdjacency& adjacency,
                                            bool ties_to_fewest_faces, uint32_t step_group = 0);

  // Up to `max_steps` (at most kHcMaxBatch) merges while more than `lowest` clusters are
  // left, into `batch` (replaced); fewer where no ODE is left (one cluster per component)
  // or the log is full (the next batch goes on). Errors name the pass.
  absl::Status Steps(uint32_t lowest, uint32_t max_steps, HcBatchGpu& batch);

  // The current labels (downloaded; for tests).
  absl::StatusOr<std::vector<uint32_t>> Labels();

 private:
  enum Binding : uint32_t {
    kSums,
    kClusters,
    kOdeCost,
    kLabels,
    kEdges,
    kEdgeNext,
    kEdgeKeys,  // the start only
    kOdes,      // the start only
    kMemberNext,
    kTree,
    kTouched,
    kStepLog,
    kLogFaces,
    kControl,
    kBindings
  };

  HcLevelsGpu(GlContext& context, uint32_t num_faces, bool tie_by_size, uint32_t program,
              std::vector<StorageBuffer> buffers)
      : context_(&context),
        num_faces_(num_faces),
        tie_by_size_(tie_by_size),
        steps_program_(program),
        buffers_(std::move(buffers)) {}

  GlContext* context_;
  uint32_t num_faces_;
  bool tie_by_size_;
  uint32_t steps_program_;
  std::vector<StorageBuffer> buffers_;  // kBindings, the start's buffers released
};

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_KERNELS_HC_LEVELS_H_
