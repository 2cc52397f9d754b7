// PML, HC and ML for points on the GPU (sections 6.4.2-6.4.3; Alg. 5.3 and Alg. 5.6 over
// the local neighbours). PML (RunPointParallelMultilevelGpu): the levels of
// core/cluster/point_clustering.h's RunPointMultilevel with options.parallel,
// the voxel start (gpu/kernels/voxel_start.h) and every level's ODEs, mutual pairs,
// collapse, triplets and neighbour refresh on the GPU (gpu/kernels/points_levels.h), the
// levels streamed to the same LevelSink. With optimizer none the levels are merges only;
// with LN k-means (the CPU's default) each level's merges are followed by the CPU's LN
// k-means rounds before the refresh (gpu/stages/points_optimise_gpu.h says who does what).
//
// What is the CPU's and what is not:
//   - the start is the CPU engine's exactly: the voxel labels (GPU), the clusters' sums
//     in the CPU's order (host: a detail::PointClusters over the points ordered by cell,
//     as PointSpace keeps them, MakePointLevelsHost; with LN k-means it stays as the
//     rounds' mirror), the face-sharing neighbours (GPU), then the CPU's sequential
//     refresh of them and its link of isolated cells (host, O(k d^2)); level 0 and its
//     energy are identical;
//   - the first level's ODEs, pairs and merges are identical (same Ward costs bit for
//     bit, same ties rule, same kept ids);
//   - after a level the GPU refreshes every live cluster's neighbours at once from the
//     table before the level, through the merges (points_refresh.glsl); the CPU refreshes
//     only the clusters the level touched, one after the other, each seeing the ones
//     before it. So later levels differ: the hierarchies are alike, not equal (the tests
//     bound the energies at equal cluster counts).
// Covered (PointsPmlGpuUnsupported says why not otherwise): PML, optimizer none or LN
// k-means (optimise_rounds and bounded_drift: the shared round driver's), pml-until (PML's
// levels down to it, then RunPointHierarchyGpu's steps; alike the CPU's, not identical),
// both pair rules, min_clusters, grid; at most kVoxelStartMaxDims dimensions.
// PointMultilevelOptions::threads is not used (the host's part of the start runs on one
// thread); inspect_level is called with each level's labels (downloaded; slow, for tests).
#ifndef MLCLUST_GPU_STAGES_POINTS_MULTILEVEL_GPU_H_
#define MLCLUST_GPU_STAGES_POINTS_MULTILEVEL_GPU_H_

#include <string>

#include "absl/status/statusor.h"
#include "core/cluster/point_clustering.h"
#include "core/hierarchy/hierarchy.h"
#include "core/plan/device_policy.h"
#include "core/points/points.h"
#include "gpu/context/gl_context.h"

namespace mlclust::gpu {

// What it covers is the device policy's PointsPmlGpuUnsupported
// (core/plan/device_policy.h).

// RunPointMultilevel's contract (level 0 the voxel clusters; then every level), plus
// UNIMPLEMENTED for options PointsPmlGpuUnsupported refuses and the GPU's errors, each
// naming its pass ("GPU pass 'points odes': ..."); CANCELLED between levels.
absl::StatusOr<PointMultilevelSummary> RunPointParallelMultilevelGpu(
    GlContext& context, const PointSet& points, const PointMultilevelOptions& options,
    LevelSink& sink);

// HC and ML for points on the GPU (options.parallel false; optimizer none: HC, LN k-means:
// ML, bounded_drift too), one merge per level (Alg. 5.6: findMinDE, collapseMinDE,
// minimizeEnergy): the same start, then per level the cheapest ODE of the CPU engine's
// queue merged (PointLevelsGpu::StepMerge), the gone cluster's points the triplets (the
// host's member lists: 4 bytes per point; ML: the mirror's), with LN k-means the CPU's
// rounds around the merge (PointLevelsOptimiser, as for PML), then the CPU's refresh of
// the touched clusters' neighbours and its ODE recomputes (StepRefresh). RunPointMultilevel's
// contract; UNIMPLEMENTED for options.parallel; the GPU's errors by pass; CANCELLED
// between levels.
// What is the CPU's: HC's levels are the CPU's level for level wherever the order of the
// refresh within a group does not matter (the GPU: by id; the CPU: its reverse lists'
// history order): every level of the tests' 2-D and 3-D sets and of 10^5 3-D points, 230
// of 730 levels in 8-D. ML: level 1 identical, then within 1% of the CPU at every count
// on the tests' 2-D and 3-D sets (8-D: 1.3% at one count near the start, under 1% from
// half the start's down; BENCHMARKS.md for 10^5 points).
// Cost: per level O(2d k0 + touched) GPU work (the ODE passes over every neighbour slot,
// the mark pass) and three read-backs (ML: more per LN k-means round); latency-bound
// (BENCHMARKS.md).
absl::StatusOr<PointMultilevelSummary> RunPointHierarchyGpu(GlContext& context,
                                                            const PointSet& points,
                                                            const PointMultilevelOptions& options,
                                                            LevelSink& sink);

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_STAGES_POINTS_MULTILEVEL_GPU_H_
