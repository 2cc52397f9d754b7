// The GPU working set of a stage: the most bytes of GPU memory the stage's kernels allocate
// (their ...MemoryBound functions), for the device policy's fit check
// (core/plan/device_policy.h DeviceCaps::gpu_working_set).
#ifndef MLCLUST_GPU_STAGES_GPU_WORKING_SET_H_
#define MLCLUST_GPU_STAGES_GPU_WORKING_SET_H_

#include <cstdint>

#include "core/plan/device_policy.h"
#include "gpu/context/gl_context.h"

namespace mlclust::gpu {

// Bytes `stage` of `plan` allocates on `context`'s device for `input` (input.elements faces
// or points; 0 where nothing is known). A bound, not a measurement: a point hierarchy is
// counted at one cluster per point (the voxel start's most). Reads only the context's
// limits, so it may be called on any thread.
uint64_t GpuWorkingSetBound(const GlContext& context, PlanStage stage, const JobPlan& plan,
                            const InputShape& input);

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_STAGES_GPU_WORKING_SET_H_
