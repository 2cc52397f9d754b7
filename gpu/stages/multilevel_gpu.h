// PML (Alg. 5.3) for meshes on the GPU: the levels of core/cluster/multilevel.h's
// RunMultilevel with options.parallel and optimizer none (merges only: PML levels as
// HC-like merges), every level's ODEs, mutual pairs, collapse and triplets on the GPU
// (gpu/kernels/pml_levels.h), the levels streamed to the same LevelSink.
//
// Covered (PmlGpuUnsupported says why not otherwise): the energies whose merge cost the
// GPU has, cvd and cvd-adaptive (both CvdEnergy); optimizer none or bb; p-percent 0;
// pml-until 0; both pair rules (all = Alg. 5.3, cheaper-half = ours).
//
// Optimizer none: the levels are the CPU engine's exactly where the GPU's fp64 is IEEE
// (llvmpipe, NVIDIA): the same merge costs bit for bit, the same ties rule (equal costs to
// the larger id) and the same kept ids. MultilevelOptions::inspect_level and threads are
// not used.
//
// Optimizer bb (Alg. 5.7: minimizeEnergy() after each collapse step): after each level's
// merges, BB sweeps as Alg. 5.4 over every face (not only around the merges, as the CPU
// engine's local BB), each sweep: proxies fitted and every face decided on the GPU
// (pml_levels.h, "pml bb decide"), the proposals read back, the CPU stage's conflict rule
// and moves (core/cluster/boundary_based.h: ResolveConflicts with the ring test or no
// guard, ApplyMoves, UndoMoves for a sweep that raises the energy) on a host Partition
// that mirrors the GPU's clusters, and the moves written back ("pml bb apply"); until no
// face moves, at most 64 sweeps a level (the CPU engine's local BB stops at 8); then the cluster
// edges rebuilt on the GPU ("pml bb edges"). The level's merges and moves go through the
// CPU engine's LevelRecorder: triplets squashed (one per face whose cluster changed over
// the level) and the energy a compensated sum of per-cluster changes. Sums on the host and
// the GPU are the same bits (the same additions). The levels differ from the CPU engine's
// PML with optimizer bb, whose local sweeps move faces one by one (Gauss-Seidel, proxies
// refitted as they go): here a sweep decides all faces against fixed proxies (Jacobi), as
// Alg. 5.4 does. inspect_level gets the GPU's labels (downloaded); threads is the
// resolve stage's.
#ifndef MLCLUST_GPU_STAGES_MULTILEVEL_GPU_H_
#define MLCLUST_GPU_STAGES_MULTILEVEL_GPU_H_

#include <string>

#include "absl/status/statusor.h"
#include "core/cluster/mesh_clustering.h"
#include "core/cluster/multilevel.h"
#include "core/hierarchy/hierarchy.h"
#include "core/plan/device_policy.h"
#include "gpu/context/gl_context.h"

namespace mlclust::gpu {

// What it covers is the device policy's PmlGpuUnsupported (core/plan/device_policy.h).

// RunMultilevel's contract (level 0 one cluster per face, energy 0; then every level),
// plus UNIMPLEMENTED for options PmlGpuUnsupported refuses and the GPU's errors, each
// naming its pass ("GPU pass 'pml odes': ..."); CANCELLED between levels.
absl::StatusOr<MultilevelSummary> RunParallelMultilevelGpu(GlContext& context,
                                                           const MeshProblem& problem,
                                                           const MultilevelOptions& options,
                                                           LevelSink& sink);

// ML (Alg. 5.6: findMinDE, collapseMinDE, minimizeEnergy) for meshes on the GPU, for
// RunMultilevel's sequential levels (not options.parallel):
//   optimizer none: HC's steps (gpu/stages/hierarchy_gpu.h, RunHierarchyGpu): the CPU
//     engine's ML with optimizer none is HC, and so are these levels;
//   optimizer bb: one merge per level (PmlLevelsGpu::Step: every ODE, the cheapest in the
//     CPU queue's order, collapsed), then BB sweeps over every face until none moves (at
//     most 64), all as PML's optimizer bb above (the same driver: decide on the GPU, the
//     CPU stage's conflict rule and moves, the LevelRecorder). The CPU engine's ML with
//     optimizer bb sweeps locally around the merge, faces one by one; the levels differ.
// Covered (MlGpuUnsupported): cvd and cvd-adaptive; guard on (ring test) or off, not
// vertex-count; p-percent 0. Errors as RunParallelMultilevelGpu, the step's choice named
// "ml min ode". What it covers is the device policy's MlGpuUnsupported.
absl::StatusOr<MultilevelSummary> RunMultilevelGpu(GlContext& context, const MeshProblem& problem,
                                                   const MultilevelOptions& options,
                                                   LevelSink& sink);

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_STAGES_MULTILEVEL_GPU_H_
