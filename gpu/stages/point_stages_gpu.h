// LN k-means (Alg. 6.1) and brute-force k-means (Lloyd; section 6.4.4) with their assign
// stage on the GPU (gpu/kernels/ln_kmeans.h, gpu/kernels/kmeans_assign.h).
#ifndef MLCLUST_GPU_STAGES_POINT_STAGES_GPU_H_
#define MLCLUST_GPU_STAGES_POINT_STAGES_GPU_H_

#include <vector>

#include "absl/status/statusor.h"
#include "core/base/ids.h"
#include "core/cluster/kmeans.h"
#include "core/cluster/point_clustering.h"
#include "core/points/points.h"
#include "gpu/context/gl_context.h"

namespace mlclust::gpu {

// RunLnKmeans (core/cluster/point_clustering.h) with the initial local neighbours (brute
// force, pass "ln-kmeans neighbours") and every iteration's assign stage (pass "ln-kmeans
// assign") on the GPU; apply and refresh are the CPU's (RunLnKmeansIterations in
// core/cluster/detail/ln_kmeans_stages.h). On a driver with IEEE fp64 the result equals
// RunLnKmeans'. Errors as RunLnKmeans, plus INVALID_ARGUMENT for more than
// kLnKmeansMaxDims dimensions and the GPU's, named by pass.
absl::StatusOr<LnKmeansResult> RunLnKmeansGpu(GlContext& context, const PointSet& points,
                                              std::vector<ClusterId> labels,
                                              const LnKmeansOptions& options = {});

// Lloyd's iterations from `centres` (k x d): RunLloyd (core/cluster/kmeans.h) with the
// assignment on the GPU (pass "kmeans assign": nearest centre in fp32). Everything after the
// assignment is RunLloyd's own loop (core/cluster/detail/lloyd.h), so its rules hold and
// where the GPU proposes the same nearest centres as the CPU's float kernel the result is
// RunLloyd's bit for bit; the two kernels may break near-ties otherwise (inertia agrees
// within 0.5%, tested). Errors as RunLloyd, plus the GPU's, named by pass.
absl::StatusOr<KmeansResult> RunLloydGpu(GlContext& context, const PointSet& points,
                                         std::vector<float> centres, const KmeansOptions& options);

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_STAGES_POINT_STAGES_GPU_H_
