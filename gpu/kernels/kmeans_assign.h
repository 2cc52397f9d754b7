// Brute-force k-means assignment (section 6.4.4) on the GPU: every point against every
// centre, m k d distance terms in fp32 (the precision of the points), the nearest centre,
// ties to the smaller index. gpu/stages/kmeans_gpu.h drives Lloyd's iterations with it.
//
// Memory: the points stay on the GPU (4 d bytes per point), the labels (4 bytes per point)
// and the centres (4 d bytes per centre); each must fit one storage buffer.
#ifndef MLCLUST_GPU_KERNELS_KMEANS_ASSIGN_H_
#define MLCLUST_GPU_KERNELS_KMEANS_ASSIGN_H_

#include <cstdint>
#include <span>
#include <utility>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "core/points/points.h"
#include "gpu/context/compute.h"
#include "gpu/context/gl_context.h"

namespace mlclust::gpu {

uint64_t KmeansAssignMemoryBound(uint64_t num_points, uint32_t dims, uint32_t num_centres);

class KmeansAssignKernel {
 public:
  // Uploads the points for k centres. INVALID_ARGUMENT for d = 0, k = 0 or indices past
  // 32 bits; RESOURCE_EXHAUSTED / INTERNAL as the other kernels; errors name the pass
  // "kmeans assign".
  static absl::StatusOr<KmeansAssignKernel> Create(GlContext& context, const PointSet& points,
                                                   uint32_t num_centres);

  // labels[i] = the nearest centre of point i. centres: k x d; labels: one per point.
  absl::Status Assign(std::span<const float> centres, std::span<uint32_t> labels);

 private:
  KmeansAssignKernel(GlContext& context, uint32_t num_points, uint32_t dims, uint32_t num_centres,
                     StorageBuffer points, StorageBuffer centres, StorageBuffer labels)
      : context_(&context),
        num_points_(num_points),
        dims_(dims),
        num_centres_(num_centres),
        points_(std::move(points)),
        centres_(std::move(centres)),
        labels_(std::move(labels)) {}

  GlContext* context_;
  uint32_t num_points_;
  uint32_t dims_;
  uint32_t num_centres_;
  StorageBuffer points_, centres_, labels_;
};

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_KERNELS_KMEANS_ASSIGN_H_
