// PML (Alg. 5.3) for meshes on the GPU: the levels of core/cluster/multilevel.h's
// RunMultilevel with options.parallel and optimizer none (merges only: PML levels as
// HC-like merges), every level's ODEs, mutual pairs, collapse and triplets on the GPU
// (gpu/kernels/pml_levels.h), the levels streamed to the same LevelSink.
//
// Covered (PmlGpuUnsupported says why not otherwise): the energies whose merge cost the
// GPU has, cvd and cvd-adaptive (both CvdEnergy); optimizer none; p-percent 0; pml-until
// 0; both pair rules (all = Alg. 5.3, cheaper-half = ours). The levels are the CPU
// engine's exactly where the GPU's fp64 is IEEE (llvmpipe, NVIDIA): the same merge costs
// bit for bit, the same ties rule (equal costs to the larger id) and the same kept ids.
// MultilevelOptions::inspect_level and threads are not used.
#ifndef MLCLUST_GPU_STAGES_MULTILEVEL_GPU_H_
#define MLCLUST_GPU_STAGES_MULTILEVEL_GPU_H_

#include <string>

#include "absl/status/statusor.h"
#include "core/cluster/mesh_clustering.h"
#include "core/cluster/multilevel.h"
#include "core/hierarchy/hierarchy.h"
#include "gpu/context/gl_context.h"

namespace mlclust::gpu {

// Empty where RunParallelMultilevelGpu covers these options and energy; else why not.
std::string PmlGpuUnsupported(const MultilevelOptions& options, MeshEnergyKind energy);

// RunMultilevel's contract (level 0 one cluster per face, energy 0; then every level),
// plus UNIMPLEMENTED for options PmlGpuUnsupported refuses and the GPU's errors, each
// naming its pass ("GPU pass 'pml odes': ..."); CANCELLED between levels.
absl::StatusOr<MultilevelSummary> RunParallelMultilevelGpu(GlContext& context,
                                                           const MeshProblem& problem,
                                                           const MultilevelOptions& options,
                                                           LevelSink& sink);

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_STAGES_MULTILEVEL_GPU_H_
