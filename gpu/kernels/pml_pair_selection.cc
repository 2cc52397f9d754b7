#include "gpu/kernels/pml_pair_selection.h"

#include <algorithm>
#include <array>
#include <cstddef>
#include <utility>

#include "absl/strings/str_cat.h"
#include "core/base/compensated_sum.h"
#include "core/base/status_macros.h"
#include "gpu/context/gl_functions.h"
#include "gpu/context/pass.h"
#include "gpu/kernels/compact_scan_glsl.h"  // kCompactScanGlsl, generated
#include "gpu/kernels/ode_min_glsl.h"       // kOdeMinGlsl, generated
#include "gpu/kernels/pml_compact_glsl.h"   // kPmlCompactGlsl, generated
#include "gpu/kernels/pml_cvd_glsl.h"       // kPmlCvdGlsl, generated
#include "gpu/kernels/pml_ode_glsl.h"       // kPmlOdeGlsl, generated

namespace mlclust::gpu {

uint32_t SelectGpuPmlPairs(PmlPairRule rule, uint32_t clusters, uint32_t floor,
                           std::span<const uint32_t> ids, std::span<const double> values,
                           std::vector<uint32_t>& selected) {
  const auto pairs = static_cast<uint32_t>(ids.size() / 2);
  struct Candidate {
    std::pair<uint32_t, uint32_t> pair;
    double cost;
    uint32_t slot;
  };
  std::vector<Candidate> chosen(pairs);
  for (uint32_t i = 0; i < pairs; ++i) {
    chosen[i] = {{ids[2 * i], ids[2 * i + 1]}, values[3 * i], i};
  }
  // The CPU's order: by the smaller cluster.
  std::sort(chosen.begin(), chosen.end(),
            [](const Candidate& x, const Candidate& y) { return x.pair < y.pair; });
  if (rule == PmlPairRule::kCheaperHalf) {
    // detail::SelectPmlPairs's rule (core/cluster/detail/pml_pairs.h): the pairs that
    // cost at most the median (the cost at index size / 2 in cost order).
    std::vector<double> costs(pairs);
    for (uint32_t i = 0; i < pairs; ++i) costs[i] = chosen[i].cost;
    std::nth_element(costs.begin(), costs.begin() + costs.size() / 2, costs.end());
    const double limit = costs[costs.size() / 2];
    chosen.erase(std::remove_if(chosen.begin(), chosen.end(),
                                [&](const Candidate& c) { return !(c.cost <= limit); }),
                 chosen.end());
  }
  if (clusters < floor + uint64_t{chosen.size()}) {
    std::sort(chosen.begin(), chosen.end(), [](const Candidate& x, const Candidate& y) {
      return x.cost != y.cost ? x.cost < y.cost : x.pair < y.pair;
    });
    chosen.resize(clusters - floor);
  }
  selected.assign(pairs, 0);
  for (const Candidate& candidate : chosen) selected[candidate.slot] = 1;
  return static_cast<uint32_t>(chosen.size());
}

absl::StatusOr<bool> SelectCollapsedPairs(PmlPairRule rule, uint32_t clusters, uint32_t lowest,
                                          uint32_t pairs, StorageBuffer& ids, StorageBuffer& values,
                                          StorageBuffer& selected, uint32_t& merged) {
  const uint32_t floor = std::max(lowest, 1u);
  const bool past_floor = clusters < floor + uint64_t{pairs};
  merged = pairs;
  if (rule == PmlPairRule::kAll && !past_floor) return false;
  std::vector<uint32_t> pair_ids(size_t{2} * pairs);
  std::vector<double> pair_values(size_t{3} * pairs);
  MLCLUST_RETURN_IF_ERROR(ids.Download(std::span<uint32_t>(pair_ids)));
  MLCLUST_RETURN_IF_ERROR(values.Download(std::span<double>(pair_values)));
  std::vector<uint32_t> flags;
  merged = SelectGpuPmlPairs(rule, clusters, floor, pair_ids, pair_values, flags);
  MLCLUST_RETURN_IF_ERROR(selected.Upload(std::span<const uint32_t>(flags)));
  return true;
}

absl::Status FindOdes(GlContext& context, const MutualPairPasses& passes) {
  // The ODE kernels' phases (pml_ode.glsl, points_ode.glsl).
  constexpr uint32_t kOdeCost = 0, kOdeLow = 1, kOdePartner = 2, kOdeReset = 3;
  const detail::GlFunctions& gl = context.gl();
  gl.UseProgram(passes.ode_program);
  if (passes.dims) gl.ProgramUniform1ui(passes.ode_program, 2, *passes.dims);
  gl.ProgramUniform1ui(passes.ode_program, 0, passes.clusters);
  gl.ProgramUniform1ui(passes.ode_program, 1, kOdeReset);
  MLCLUST_RETURN_IF_ERROR(DispatchLinear(context, passes.clusters));
  for (const uint32_t phase : {kOdeCost, kOdeLow, kOdePartner}) {
    gl.MemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    gl.ProgramUniform1ui(passes.ode_program, 0, passes.edges);
    gl.ProgramUniform1ui(passes.ode_program, 1, phase);
    MLCLUST_RETURN_IF_ERROR(DispatchLinear(context, passes.edges));
  }
  gl.MemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  gl.UseProgram(0);
  return absl::OkStatus();
}

absl::StatusOr<uint32_t> FindMutualPairs(GlContext& context, StorageBuffer& counters,
                                         const MutualPairPasses& passes) {
  const detail::GlFunctions& gl = context.gl();
  const std::array<uint32_t, 4> zeros{};
  MLCLUST_RETURN_IF_ERROR(counters.Upload(std::span<const uint32_t>(zeros)));
  MLCLUST_RETURN_IF_ERROR(FindOdes(context, passes));
  gl.UseProgram(passes.pairs_program);
  if (passes.dims) gl.ProgramUniform1ui(passes.pairs_program, 2, *passes.dims);
  gl.ProgramUniform1ui(passes.pairs_program, 0, passes.clusters);
  MLCLUST_RETURN_IF_ERROR(DispatchLinear(context, passes.clusters));
  gl.UseProgram(0);
  uint32_t pairs = 0;
  MLCLUST_RETURN_IF_ERROR(counters.Download(0, &pairs, 4));
  MLCLUST_RETURN_IF_ERROR(CheckGlError(context, passes.pass));
  return pairs;
}

absl::StatusOr<uint32_t> RunOdesPass(GlContext& context, const PmlLevelPasses& passes,
                                     absl::FunctionRef<absl::StatusOr<uint32_t>()> find_pairs,
                                     GpuPmlLevel& level) {
  MLCLUST_RETURN_IF_ERROR(BeginPass(context, passes.odes));
  const absl::StatusOr<uint32_t> pairs = find_pairs();
  if (!pairs.ok()) return PassError(passes.odes, pairs.status());
  level.mutual_pairs = *pairs;
  return *pairs;
}

absl::Status RunCollapsePasses(GlContext& context, const PmlLevelPasses& passes,
                               absl::FunctionRef<absl::Status()> collapse,
                               absl::FunctionRef<absl::Status()> extract) {
  MLCLUST_RETURN_IF_ERROR(BeginPass(context, passes.collapse));
  const absl::Status collapsed = collapse();
  if (!collapsed.ok()) return PassError(passes.collapse, collapsed);
  MLCLUST_RETURN_IF_ERROR(BeginPass(context, passes.triplets));
  return PassError(passes.triplets, extract());
}

absl::StatusOr<bool> RunPmlLevelPasses(GlContext& context, const PmlLevelPasses& passes,
                                       absl::FunctionRef<absl::StatusOr<uint32_t>()> find_pairs,
                                       absl::FunctionRef<absl::Status(uint32_t)> collapse,
                                       absl::FunctionRef<absl::Status(uint32_t)> extract,
                                       GpuPmlLevel& level) {
  MLCLUST_ASSIGN_OR_RETURN(const uint32_t pairs, RunOdesPass(context, passes, find_pairs, level));
  if (pairs == 0) return false;
  MLCLUST_RETURN_IF_ERROR(RunCollapsePasses(
      context, passes, [&] { return collapse(pairs); }, [&] { return extract(pairs); }));
  return true;
}

absl::Status DispatchPairMerge(GlContext& context, uint32_t merge_program, uint32_t pairs,
                               bool use_flags) {
  const detail::GlFunctions& gl = context.gl();
  gl.UseProgram(merge_program);
  gl.ProgramUniform1ui(merge_program, 0, pairs);
  gl.ProgramUniform1ui(merge_program, 1, use_flags ? 1u : 0u);
  MLCLUST_RETURN_IF_ERROR(DispatchLinear(context, pairs));
  gl.MemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  gl.UseProgram(0);
  return absl::OkStatus();
}

absl::Status MergeSelectedPairs(GlContext& context, uint32_t merge_program, PmlPairRule rule,
                                uint32_t clusters, uint32_t lowest, uint32_t pairs,
                                StorageBuffer& ids, StorageBuffer& values, StorageBuffer& selected,
                                uint32_t& merged) {
  MLCLUST_ASSIGN_OR_RETURN(
      const bool use_flags,
      SelectCollapsedPairs(rule, clusters, lowest, pairs, ids, values, selected, merged));
  return DispatchPairMerge(context, merge_program, pairs, use_flags);
}

absl::StatusOr<uint32_t> GetPmlOdeProgram(GlContext& context) {
  return GetComputeProgram(
      context, "pml_ode",
      absl::StrCat(kComputeShaderPrelude, kPmlCvdGlsl, kPmlOdeGlsl, kOdeMinGlsl));
}

absl::StatusOr<uint32_t> GetPmlCompactProgram(GlContext& context) {
  return GetComputeProgram(context, "pml_compact",
                           absl::StrCat(kComputeShaderPrelude, kPmlCompactGlsl, kCompactScanGlsl));
}

absl::Status CompactInOrder(GlContext& context, uint32_t program, uint32_t kind, uint32_t count,
                            StorageBuffer& counters, uint32_t slot) {
  // pml_compact.glsl's phases.
  constexpr uint32_t kCount = 0, kScanGroups = 1, kScanTop = 2, kWrite = 3;
  if (count == 0) {
    const uint32_t zero = 0;
    return counters.Upload(slot * 4, &zero, 4);
  }
  const detail::GlFunctions& gl = context.gl();
  const uint64_t chunks = PmlChunks(count), groups = PmlGroups(count);
  gl.UseProgram(program);
  gl.ProgramUniform1ui(program, 2, kind);
  gl.ProgramUniform1ui(program, 3, slot);
  const std::array<std::pair<uint32_t, uint64_t>, 4> steps = {
      std::pair<uint32_t, uint64_t>{kCount, chunks},
      {kScanGroups, groups},
      {kScanTop, 1},
      {kWrite, chunks}};
  for (const auto& [phase, invocations] : steps) {
    const uint64_t elements = phase == kScanGroups ? chunks : phase == kScanTop ? groups : count;
    gl.ProgramUniform1ui(program, 0, static_cast<uint32_t>(elements));
    gl.ProgramUniform1ui(program, 1, phase);
    MLCLUST_RETURN_IF_ERROR(DispatchLinear(context, invocations));
    gl.MemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  }
  gl.UseProgram(0);
  return absl::OkStatus();
}

absl::Status ReadLevelTriplets(uint32_t moved, uint32_t pairs, StorageBuffer& triplets,
                               StorageBuffer& pair_values, GpuPmlLevel& level) {
  std::vector<uint32_t> words(size_t{3} * moved);
  if (moved > 0) MLCLUST_RETURN_IF_ERROR(triplets.Download(std::span<uint32_t>(words)));
  std::vector<double> values(size_t{3} * pairs);
  MLCLUST_RETURN_IF_ERROR(pair_values.Download(std::span<double>(values)));
  level.element.resize(moved);
  level.to_cluster.resize(moved);
  level.from_cluster.resize(moved);
  for (uint32_t i = 0; i < moved; ++i) {
    level.element[i] = words[3 * i];
    level.to_cluster[i] = words[3 * i + 1];
    level.from_cluster[i] = words[3 * i + 2];
  }
  ::mlclust::detail::CompensatedSum change;
  change.Reset(0);
  for (uint32_t i = 0; i < pairs; ++i) {
    change.Add(values[3 * i + 1]);
    change.Add(values[3 * i + 2]);
  }
  level.energy_change = change.value();
  return absl::OkStatus();
}

}  // namespace mlclust::gpu
