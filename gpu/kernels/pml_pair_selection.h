// The host side of one GPU PML level, shared by the mesh (pml_levels.h) and the point
// (points_levels.h) engines: the mutual-pair passes, which of a level's mutual pairs the
// merge pass collapses, the stream compaction (pml_compact.glsl) and the level's
// read-back.
#ifndef MLCLUST_GPU_KERNELS_PML_PAIR_SELECTION_H_
#define MLCLUST_GPU_KERNELS_PML_PAIR_SELECTION_H_

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "absl/functional/function_ref.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "core/cluster/detail/pml_pairs.h"
#include "gpu/context/compute.h"
#include "gpu/context/gl_context.h"

namespace mlclust::gpu {

// Elements per invocation and invocations per scan group of pml_compact.glsl.
inline constexpr uint32_t kPmlChunk = 32;
inline constexpr uint32_t kPmlGroup = 256;

// pml_compact.glsl's invocations (chunks of kPmlChunk elements) and scan groups (of
// kPmlGroup chunks) over `count` elements: what its chunk and group buffers hold.
inline constexpr uint64_t PmlChunks(uint64_t count) { return (count + kPmlChunk - 1) / kPmlChunk; }
inline constexpr uint64_t PmlGroups(uint64_t count) {
  return (PmlChunks(count) + kPmlGroup - 1) / kPmlGroup;
}

// One level's result (PmlLevelsGpu::Level, PointLevelsGpu::Level).
struct GpuPmlLevel {
  uint32_t mutual_pairs = 0;  // found (before the pair rule and the lowest level)
  uint32_t merged = 0;        // collapsed
  double energy_change = 0;   // sum of E(after) - E(before) over the changed clusters
  // The triplets, in element order (faces or points).
  std::vector<uint32_t> element, to_cluster, from_cluster;
};

// The CPU engine's selection (ParallelMerges) on the level's `ids` (2 per pair: the two
// clusters) and `values` (3 per pair, the first the merge cost): the pair rule, then the
// cheapest (cost, then pair) down to `floor` clusters from `clusters`. Sets `selected`
// (one flag per pair, in the GPU's pair order) and returns how many pairs it keeps.
uint32_t SelectGpuPmlPairs(PmlPairRule rule, uint32_t clusters, uint32_t floor,
                           std::span<const uint32_t> ids, std::span<const double> values,
                           std::vector<uint32_t>& selected);

// The selection of one collapse of `pairs` mutual pairs at `clusters` clusters down to
// `lowest`: where the rule is kAll and the level stays above the floor, every pair (false,
// `merged` = pairs); otherwise (true) SelectGpuPmlPairs on the pairs read from `ids` and
// `values`, its flags written into `selected` and `merged` their count.
absl::StatusOr<bool> SelectCollapsedPairs(PmlPairRule rule, uint32_t clusters, uint32_t lowest,
                                          uint32_t pairs, StorageBuffer& ids, StorageBuffer& values,
                                          StorageBuffer& selected, uint32_t& merged);

// One level's mutual-pair passes, as the mesh and the point levels run them: the ODE
// program (uniforms 0: count, 1: phase) reset per cluster, then its cost, low and partner
// phases per edge (or neighbour slot), then the pairs program per cluster; with `dims`,
// uniform 2 of both programs.
struct MutualPairPasses {
  uint32_t ode_program = 0, pairs_program = 0;
  uint32_t clusters = 0, edges = 0;
  std::optional<uint32_t> dims;
  const char* pass = "";  // the GPU pass named in errors
};

// The ODE program's phases of `passes` alone (every cluster's ODE; not the pairs
// program): what ML's step (PmlLevelsGpu::Step) needs before its own choice. The buffers
// are bound by the caller.
absl::Status FindOdes(GlContext& context, const MutualPairPasses& passes);

// Zeroes the 4 counter slots of `counters`, runs `passes` (FindOdes, then the pairs
// program) and returns the pairs found (counter slot 0). The buffers are bound by the
// caller.
absl::StatusOr<uint32_t> FindMutualPairs(GlContext& context, StorageBuffer& counters,
                                         const MutualPairPasses& passes);

// The GPU passes of one PML level, named in errors and by MLCLUST_GPU_FAIL_PASS.
struct PmlLevelPasses {
  const char* odes = "";      // the optimal dual edges and the mutual pairs
  const char* collapse = "";  // the merges of the selected pairs
  const char* triplets = "";  // the compaction and the level's read-back
};

// Pass `passes.odes` of a level: find_pairs(), its count into level.mutual_pairs.
absl::StatusOr<uint32_t> RunOdesPass(GlContext& context, const PmlLevelPasses& passes,
                                     absl::FunctionRef<absl::StatusOr<uint32_t>()> find_pairs,
                                     GpuPmlLevel& level);

// The passes of a level after its ODEs: collapse() in pass `passes.collapse`, then
// extract() in pass `passes.triplets`.
absl::Status RunCollapsePasses(GlContext& context, const PmlLevelPasses& passes,
                               absl::FunctionRef<absl::Status()> collapse,
                               absl::FunctionRef<absl::Status()> extract);

// One PML level as the mesh and the point levels run it: RunOdesPass, and where it found
// pairs, RunCollapsePasses with collapse(pairs) and extract(pairs). False (nothing
// changed) where there is no mutual pair.
absl::StatusOr<bool> RunPmlLevelPasses(GlContext& context, const PmlLevelPasses& passes,
                                       absl::FunctionRef<absl::StatusOr<uint32_t>()> find_pairs,
                                       absl::FunctionRef<absl::Status(uint32_t)> collapse,
                                       absl::FunctionRef<absl::Status(uint32_t)> extract,
                                       GpuPmlLevel& level);

// The merge pass alone: `merge_program` (uniforms 0, the pairs, and 1, whether it reads
// the flags; the caller sets any others) over `pairs` pairs. The buffers are bound by the
// caller.
absl::Status DispatchPairMerge(GlContext& context, uint32_t merge_program, uint32_t pairs,
                               bool use_flags);

// The collapse of `pairs` mutual pairs: SelectCollapsedPairs, then DispatchPairMerge over
// the pairs. The buffers are bound by the caller.
absl::Status MergeSelectedPairs(GlContext& context, uint32_t merge_program, PmlPairRule rule,
                                uint32_t clusters, uint32_t lowest, uint32_t pairs,
                                StorageBuffer& ids, StorageBuffer& values, StorageBuffer& selected,
                                uint32_t& merged);

// The ODE program of the mesh levels (pml_cvd.glsl, pml_ode.glsl, ode_min.glsl),
// "pml_ode"; PML's and HC's (hc_levels.h).
absl::StatusOr<uint32_t> GetPmlOdeProgram(GlContext& context);

// The program of pml_compact.glsl (with compact_scan.glsl), "pml_compact".
absl::StatusOr<uint32_t> GetPmlCompactProgram(GlContext& context);

// The stream compaction of pml_compact.glsl (`program`) over `count` elements of `kind`
// in its four phases, the kept count to counter `slot` of `counters` (written 0 where
// `count` is 0). The buffers are bound by the caller.
absl::Status CompactInOrder(GlContext& context, uint32_t program, uint32_t kind, uint32_t count,
                            StorageBuffer& counters, uint32_t slot);

// The level's read-back: `moved` triplets (element, new, old) from `triplets` into
// `level`'s element, to_cluster and from_cluster, and its energy change, the compensated
// sum of the energy changes of the `pairs` pairs in `pair_values` (3 per pair: cost, then
// the kept and the gone cluster's change).
absl::Status ReadLevelTriplets(uint32_t moved, uint32_t pairs, StorageBuffer& triplets,
                               StorageBuffer& pair_values, GpuPmlLevel& level);

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_KERNELS_PML_PAIR_SELECTION_H_
