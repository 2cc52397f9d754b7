// Boundary-based optimisation (Alg. 5.1) with its decide stage on the GPU (Alg. 5.4/5.5,
// gpu/kernels/bb_decide.h) and every other stage the CPU's (core/cluster/boundary_based.h:
// fit proxies, the conflict rule with the connectivity guard, apply), so the result
// differs from OptimizeBoundaryBased's only where the device's arithmetic differs.
#ifndef MLCLUST_GPU_STAGES_BOUNDARY_BASED_GPU_H_
#define MLCLUST_GPU_STAGES_BOUNDARY_BASED_GPU_H_

#include <vector>

#include "absl/status/statusor.h"
#include "core/base/ids.h"
#include "core/cluster/mesh_clustering.h"
#include "core/energy/energies.h"
#include "gpu/context/gl_context.h"

namespace mlclust::gpu {

// OptimizeBoundaryBased (core/cluster/mesh_clustering.h) with the decide stage on
// `context`; the same contract, plus: FAILED_PRECONDITION for an energy without a GPU
// decide (HasGpuBoundaryDecide, core/plan/device_policy.h) and the GPU's errors, named by pass
// ("GPU pass 'bb decide': ..."): RESOURCE_EXHAUSTED where the buffers do not fit, INTERNAL on GL
// errors. On an error `labels` are unchanged. Runs on the context's thread.
absl::StatusOr<OptimizeResult> OptimizeBoundaryBasedGpu(GlContext& context,
                                                        const MeshProblem& problem,
                                                        std::vector<ClusterId>& labels,
                                                        const BoundaryBasedOptions& options = {});

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_STAGES_BOUNDARY_BASED_GPU_H_
