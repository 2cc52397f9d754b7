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

// Lloyd's iterations from `centres` (k x d) as RunLloyd (core/cluster/kmeans.h) with the
// assignment on the GPU (pass "kmeans assign": nearest centre in fp32). The rest on the
// CPU in fp64, with RunLloyd's rules: a point leaves its cluster only where that lowers
// its distance in double (the energy never rises), an empty cluster takes the point
// farthest from its centre among clusters of more than one point (ties to the smaller
// id), stop after options.max_iterations, an iteration that moved no point, or a centre
// shift <= options.tolerance x the mean variance. Not bit-identical with RunLloyd, whose
// float kernel may break near-ties otherwise; inertia agrees within 0.5% (tested).
// The host's O(m d) work runs on options.threads threads (0: all), in blocks whose sums
// are added in order (the result does not depend on the thread count). Errors as RunLloyd, plus the
// GPU's, named by pass.
absl::StatusOr<KmeansResult> RunLloydGpu(GlContext& context, const PointSet& points,
                                         std::vector<float> centres, const KmeansOptions& options);

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_STAGES_POINT_STAGES_GPU_H_
