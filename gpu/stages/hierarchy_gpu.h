// HC for meshes on the GPU (Alg. 2.3 as the one-collapse-per-step loop of Alg. 5.6, merges
// only): the levels of core/cluster/multilevel.h's RunMultilevel with optimizer none (no
// PML), every step's ODE updates, collapse and triplets on the GPU
// (gpu/kernels/hc_levels.h), the levels streamed to the same LevelSink, one per merge.
//
// Covered (HcGpuUnsupported says why not otherwise): the energies whose merge cost the GPU
// has, cvd and cvd-adaptive (both CvdEnergy), on triangles (not problem.polygons);
// optimizer none; not parallel (PML is gpu/stages/multilevel_gpu.h); p-percent 0; both
// tie rules (ties_to_fewest_faces). The levels are the CPU engine's exactly where the GPU's
// fp64 is IEEE (llvmpipe, NVIDIA): the same pairs, triplets (in the same order) and
// energies. MultilevelOptions::inspect_level and threads are not used. ML with optimizer
// none is HC: RunMultilevelGpu (multilevel_gpu.h) runs it here.
#ifndef MLCLUST_GPU_STAGES_HIERARCHY_GPU_H_
#define MLCLUST_GPU_STAGES_HIERARCHY_GPU_H_

#include <string>

#include "absl/status/statusor.h"
#include "core/cluster/mesh_clustering.h"
#include "core/cluster/multilevel.h"
#include "core/hierarchy/hierarchy.h"
#include "core/plan/device_policy.h"
#include "gpu/context/gl_context.h"

namespace mlclust::gpu {

// What it covers is the device policy's HcGpuUnsupported (core/plan/device_policy.h).

// RunMultilevel's contract (level 0 one cluster per face, energy 0; then one level per
// merge), plus UNIMPLEMENTED for what HcGpuUnsupported refuses (and polygons) and the
// GPU's errors, each naming its pass ("GPU pass 'hc collapse': ..."); CANCELLED between
// batches of steps (at most kHcMaxBatch merges apart).
absl::StatusOr<MultilevelSummary> RunHierarchyGpu(GlContext& context, const MeshProblem& problem,
                                                  const MultilevelOptions& options,
                                                  LevelSink& sink);

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_STAGES_HIERARCHY_GPU_H_
