// The voxel-grid start of data clustering (section 6.2, eqs. 6.2/6.3) on the GPU: the
// bounding box, every point's cell, the occupied cells compacted to cluster ids in the
// order of their first point and the face-sharing occupied cells as each cluster's first
// neighbours (voxel_start.glsl). The labels are core/cluster/point_clustering.h's
// VoxelGridStart's exactly (same cells per axis, same cell arithmetic, same numbering);
// the neighbours are the face-sharing cells the CPU's engine starts from, before its
// refresh (eq. 6.1) and before isolated cells are linked.
//
// Pass (errors and MLCLUST_GPU_FAIL_PASS): "voxel start".
//
// Memory (VoxelStartMemoryBound), bytes per point: 4d (points) + 4 (slot) + 4 (label) +
// 8d (neighbours, at most one cluster per point) + 4 (first point of a cluster) + the
// hash table of 2^b >= 2m slots at 12 bytes (24-48 per point) + the compaction's counts:
// about 40 + 12d + 48 bytes per point, 105 MB for 10^6 3-D points.
#ifndef MLCLUST_GPU_KERNELS_VOXEL_START_H_
#define MLCLUST_GPU_KERNELS_VOXEL_START_H_

#include <atomic>
#include <cstdint>
#include <vector>

#include "absl/status/statusor.h"
#include "core/points/points.h"
#include "gpu/context/gl_context.h"

namespace mlclust::gpu {

// The most dimensions the voxel start (and the point levels) take on the GPU.
inline constexpr uint32_t kVoxelStartMaxDims = 64;

struct VoxelStartGpuResult {
  std::vector<uint32_t> labels;          // per point, 0..clusters-1 (VoxelGridStart's)
  uint32_t clusters = 0;                 // occupied cells
  std::vector<uint32_t> cells_per_axis;  // d
  // clusters x 2d: the occupied cell one step up (2j) and down (2j + 1) along axis j;
  // 0xFFFFFFFF where that cell is empty or outside the grid.
  std::vector<uint32_t> neighbours;
};

// The bytes VoxelGridStartGpu allocates for m points in d dimensions.
uint64_t VoxelStartMemoryBound(uint64_t m, uint32_t d);

// VoxelGridStart(points, grid, cancel) on the GPU, plus the face-sharing neighbours.
// `grid` 0 chooses the cells per axis as the CPU does (PointMultilevelOptions::grid); in
// the high-dimensional case each trial grid's occupied cells are counted on the GPU.
// INVALID_ARGUMENT as VoxelGridStart, for more than kVoxelStartMaxDims dimensions or more
// points than 32-bit indices allow; CANCELLED once `cancel` is set (between passes);
// the GPU's errors naming the pass.
absl::StatusOr<VoxelStartGpuResult> VoxelGridStartGpu(GlContext& context, const PointSet& points,
                                                      uint32_t grid,
                                                      const std::atomic<bool>* cancel = nullptr);

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_KERNELS_VOXEL_START_H_
