// The seeding stage with its growth on the GPU: core's InitialClusters
// (core/cluster/mesh_clustering.h) with SeedOptions::Growth::kRounds grown by
// gpu/kernels/seed_growth.h (section 5.2, Fig. 5.9). Seeds, the reduction to k and the
// seed adding stay the CPU's; every growth they ask for runs on the GPU, so the result
// equals the CPU's kRounds exactly. With polygons (MeshProblem::polygons) the growth is
// the CPU's (the GPU pass takes triangles).
#ifndef MLCLUST_GPU_STAGES_SEED_GROWTH_GPU_H_
#define MLCLUST_GPU_STAGES_SEED_GROWTH_GPU_H_

#include <vector>

#include "absl/status/statusor.h"
#include "core/base/ids.h"
#include "core/cluster/mesh_clustering.h"
#include "gpu/context/gl_context.h"

namespace mlclust::gpu {

// SeedOptions::device_rounds over `context` (which must outlive it; call it on the
// context's thread).
SeedOptions::DeviceGrowth GpuRoundsGrowth(GlContext& context);

// InitialClusters(problem, options) with options.growth kRounds on the GPU; other growths
// are the CPU's (the plan puts the seed stage on the GPU for kRounds only). Same contract,
// plus the GPU's errors naming the pass "initial growth".
absl::StatusOr<std::vector<ClusterId>> InitialClustersGpu(GlContext& context,
                                                          const MeshProblem& problem,
                                                          SeedOptions options);

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_STAGES_SEED_GROWTH_GPU_H_
