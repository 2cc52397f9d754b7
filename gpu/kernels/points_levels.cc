#include "gpu/kernels/points_levels.h"

#include <algorithm>
#include <array>
#include <cstring>
#include <string>

#include "absl/strings/str_cat.h"
#include "core/base/compensated_sum.h"
#include "core/base/status_macros.h"
#include "gpu/context/gl_functions.h"
#include "gpu/context/pass.h"
#include "gpu/kernels/ml_min_ode_glsl.h"    // kMlMinOdeGlsl, generated
#include "gpu/kernels/mutual_pairs_glsl.h"  // kMutualPairsGlsl, generated
#include "gpu/kernels/ode_min_glsl.h"       // kOdeMinGlsl, generated
#include "gpu/kernels/pair_merge_glsl.h"    // kPairMergeGlsl, generated
#include "gpu/kernels/pml_pair_selection.h"
#include "gpu/kernels/points_common_glsl.h"   // kPointsCommonGlsl, generated
#include "gpu/kernels/points_hc_glsl.h"       // kPointsHcGlsl, generated
#include "gpu/kernels/points_merge_glsl.h"    // kPointsMergeGlsl, generated
#include "gpu/kernels/points_ode_glsl.h"      // kPointsOdeGlsl, generated
#include "gpu/kernels/points_pairs_glsl.h"    // kPointsPairsGlsl, generated
#include "gpu/kernels/points_refresh_glsl.h"  // kPointsRefreshGlsl, generated
#include "gpu/kernels/points_update_glsl.h"   // kPointsUpdateGlsl, generated
#include "gpu/kernels/voxel_start.h"

namespace mlclust::gpu {
namespace {

constexpr char kOdesPass[] = "points odes";
constexpr char kCollapsePass[] = "points collapse";
constexpr char kTripletsPass[] = "points triplets";
constexpr PmlLevelPasses kLevelPasses{kOdesPass, kCollapsePass, kTripletsPass};
constexpr char kNeighboursPass[] = "points neighbours";
constexpr char kUpdatePass[] = "points update";
constexpr char kReadBackPass[] = "points read-back";
constexpr char kHcOdesPass[] = "points hc odes";
constexpr char kHcSelectPass[] = "points hc select";
constexpr char kHcNeighboursPass[] = "points hc neighbours";
// points_hc.glsl's phases.
constexpr uint32_t kHcMark = 0, kHcOrder = 1, kHcRefresh = 2, kHcFinish = 3, kHcCommit = 4,
                   kHcRepair = 5, kHcGather = 6, kHcNeeded = 7, kHcMerged = 8, kHcPlaces = 9;
// points_ode.glsl's u_needed_at (0: every edge; HC's and ML's steps: the flags' offset).
constexpr uint32_t kOdeNeededAt = 9;
// points_hc.glsl's work buffer, uints: state, touched, listed, ordered, groups, flags (k
// each), then the gathered rows (k + 1 of 2d).
uint64_t HcWorkUints(uint64_t k, uint32_t d) { return 4 + 5 * k + (k + 1) * 2 * d; }
constexpr uint32_t kNone = 0xFFFFFFFFu;

// pml_compact.glsl's kind and counter slots (shared with the meshes' PML).
constexpr uint32_t kElements = 0;
constexpr uint32_t kPairSlot = 0, kTripletSlot = 1, kCounterSlots = 4;
// FindMutualPairs (pml_pair_selection.h) zeroes 4 counter slots and reads the pairs' slot 0.
static_assert(kPairSlot == 0 && kCounterSlots == 4);

uint64_t MaxPairs(uint64_t k) { return k / 2 + 1; }
// Update's two staging buffers at their largest, bytes: ids (a cluster's id and count, a
// point's id and label) and values (2d + 1 per cluster).
std::array<uint64_t, 2> UpdateStagingBytes(uint64_t m, uint64_t k, uint32_t d) {
  const uint64_t n = std::max<uint64_t>(m, 1), c = std::max<uint64_t>(k, 1);
  return {8 * (n + c), 8 * c * (2 * uint64_t{d} + 1)};
}

}  // namespace

uint64_t PointLevelsMemoryBound(uint64_t m, uint64_t k, uint32_t d) {
  const uint64_t n = std::max<uint64_t>(m, 1), c = std::max<uint64_t>(k, 1);
  return n * 16 + PmlChunks(n) * 4 + PmlGroups(n) * 4 + kCounterSlots * 4 +
         c * (4 + 8 * d + 8 * (d + 1) + 4 + 16 * d + 12 + 16 * d + 8) + MaxPairs(c) * 36 + c * 12 +
         HcWorkUints(c, d) * 4 + UpdateStagingBytes(m, k, d)[0] + UpdateStagingBytes(m, k, d)[1];
}

absl::StatusOr<PointLevelsGpu> PointLevelsGpu::Create(GlContext& context,
                                                      const PointLevelsStart& start) {
  const uint32_t d = start.dims;
  const uint64_t m = start.labels.size(), k = start.counts.size();
  if (d == 0 || d > kVoxelStartMaxDims) {
    return absl::InvalidArgumentError(
        absl::StrCat("points levels: ", d, " dimensions (1 to ", kVoxelStartMaxDims, ")"));
  }
  if (start.sums.size() != k * (d + 1) || start.centroids.size() != k * d ||
      start.neighbours.size() != k * 2 * d) {
    return absl::InvalidArgumentError(
        absl::StrCat("points levels: sums, centroids or neighbours do not fit ", k, " clusters"));
  }
  if (m * 3 >= (uint64_t{1} << 32) || k * 2 * d * 2 >= (uint64_t{1} << 32)) {
    return absl::InvalidArgumentError(
        absl::StrCat("points levels: ", m, " points or ", k, " clusters are too many"));
  }
  for (const uint32_t label : start.labels) {
    if (label >= k) return absl::InvalidArgumentError("points levels: a label out of range");
  }
  for (const uint32_t n : start.neighbours) {
    if (n != kNone && n >= k) {
      return absl::InvalidArgumentError("points levels: a neighbour out of range");
    }
  }
  MLCLUST_RETURN_IF_ERROR(BeginPass(context, kOdesPass));
  absl::StatusOr<PointLevelsGpu> made = [&]() -> absl::StatusOr<PointLevelsGpu> {
    const uint64_t n = std::max<uint64_t>(m, 1), c = std::max<uint64_t>(k, 1);
    const uint64_t chunks = PmlChunks(n), groups = PmlGroups(n);
    const std::array<uint64_t, kBindings> bytes = {c * 4,
                                                   c * d * 8,
                                                   n * 4,
                                                   c * 4,
                                                   c * 2 * d * 4,
                                                   c * 2 * d * 4,
                                                   c * (d + 1) * 8,
                                                   c * 12,
                                                   MaxPairs(c) * 8,
                                                   MaxPairs(c) * 24,
                                                   MaxPairs(c) * 4,
                                                   chunks * 4,
                                                   groups * 4,
                                                   kCounterSlots * 4,
                                                   n * 12,
                                                   c * 8,
                                                   c * 2 * d * 8,
                                                   c * 12,
                                                   HcWorkUints(c, d) * 4};
    MLCLUST_ASSIGN_OR_RETURN(std::vector<StorageBuffer> buffers,
                             CreateStorageBuffers(context, bytes));
    std::vector<uint32_t> identity(k), partner(2 * k, kNone);
    for (uint32_t i = 0; i < k; ++i) identity[i] = i;
    if (m > 0) MLCLUST_RETURN_IF_ERROR(buffers[kLabels].Upload(start.labels));
    if (k > 0) {
      MLCLUST_RETURN_IF_ERROR(buffers[kCounts].Upload(start.counts));
      MLCLUST_RETURN_IF_ERROR(buffers[kCentroids].Upload(start.centroids));
      MLCLUST_RETURN_IF_ERROR(buffers[kSums].Upload(start.sums));
      MLCLUST_RETURN_IF_ERROR(buffers[kNeighboursIn].Upload(start.neighbours));
      MLCLUST_RETURN_IF_ERROR(buffers[kRemap].Upload(std::span<const uint32_t>(identity)));
      MLCLUST_RETURN_IF_ERROR(buffers[kPartner].Upload(std::span<const uint32_t>(partner)));
    }
    Programs programs;
    const std::string prelude = absl::StrCat(kComputeShaderPrelude, kPointsCommonGlsl);
    MLCLUST_ASSIGN_OR_RETURN(programs.ode,
                             GetComputeProgram(context, "points_ode",
                                               absl::StrCat(prelude, kPointsOdeGlsl, kOdeMinGlsl)));
    MLCLUST_ASSIGN_OR_RETURN(
        programs.pairs,
        GetComputeProgram(context, "points_pairs",
                          absl::StrCat(prelude, kPointsPairsGlsl, kMutualPairsGlsl)));
    MLCLUST_ASSIGN_OR_RETURN(
        programs.merge, GetComputeProgram(context, "points_merge",
                                          absl::StrCat(prelude, kPointsMergeGlsl, kPairMergeGlsl)));
    MLCLUST_ASSIGN_OR_RETURN(
        programs.refresh,
        GetComputeProgram(context, "points_refresh", absl::StrCat(prelude, kPointsRefreshGlsl)));
    MLCLUST_ASSIGN_OR_RETURN(
        programs.update,
        GetComputeProgram(context, "points_update", absl::StrCat(prelude, kPointsUpdateGlsl)));
    MLCLUST_ASSIGN_OR_RETURN(
        programs.hc, GetComputeProgram(context, "points_hc", absl::StrCat(prelude, kPointsHcGlsl)));
    MLCLUST_ASSIGN_OR_RETURN(programs.min_ode,
                             GetComputeProgram(context, "ml_min_ode",
                                               absl::StrCat(kComputeShaderPrelude, kMlMinOdeGlsl)));
    MLCLUST_ASSIGN_OR_RETURN(programs.compact, GetPmlCompactProgram(context));
    MLCLUST_RETURN_IF_ERROR(CheckGlError(context, kOdesPass));
    return PointLevelsGpu(context, static_cast<uint32_t>(m), static_cast<uint32_t>(k), d, programs,
                          std::move(buffers));
  }();
  if (!made.ok()) return PassError(kOdesPass, made.status());
  return made;
}

void PointLevelsGpu::BindAll() {
  for (uint32_t b = 0; b < kBindings; ++b) buffers_[b].Bind(b);
}

absl::StatusOr<uint32_t> PointLevelsGpu::FindPairs() {
  BindAll();
  context_->gl().ProgramUniform1ui(programs_.ode, kOdeNeededAt, 0);  // every edge
  return FindMutualPairs(*context_, buffers_[kCounters],
                         {programs_.ode, programs_.pairs, k_, k_ * 2 * d_, d_, kOdesPass});
}

absl::Status PointLevelsGpu::Collapse(PmlPairRule rule, uint32_t clusters, uint32_t lowest,
                                      uint32_t pairs, PointLevelGpu& level) {
  const detail::GlFunctions& gl = context_->gl();
  gl.ProgramUniform1ui(programs_.merge, 2, d_);
  gl.ProgramUniform1ui(programs_.merge, 3, level_);
  MLCLUST_RETURN_IF_ERROR(MergeSelectedPairs(*context_, programs_.merge, rule, clusters, lowest,
                                             pairs, buffers_[kPairIds], buffers_[kPairValues],
                                             buffers_[kPairSelected], level.merged));
  return CheckGlError(*context_, kCollapsePass);
}

absl::Status PointLevelsGpu::Extract(uint32_t pairs, PointLevelGpu& level) {
  MLCLUST_RETURN_IF_ERROR(CompactInOrder(*context_, programs_.compact, kElements, m_,
                                         buffers_[kCounters], kTripletSlot));
  std::array<uint32_t, kCounterSlots> counters{};
  MLCLUST_RETURN_IF_ERROR(buffers_[kCounters].Download(std::span<uint32_t>(counters)));
  MLCLUST_RETURN_IF_ERROR(ReadLevelTriplets(counters[kTripletSlot], pairs, buffers_[kTriplets],
                                            buffers_[kPairValues], level));
  return CheckGlError(*context_, kTripletsPass);
}

absl::Status PointLevelsGpu::Refresh(bool link_all) {
  const detail::GlFunctions& gl = context_->gl();
  BindAll();
  gl.UseProgram(programs_.refresh);
  gl.ProgramUniform1ui(programs_.refresh, 0, k_);
  gl.ProgramUniform1ui(programs_.refresh, 2, d_);
  gl.ProgramUniform1ui(programs_.refresh, 3, level_);
  gl.ProgramUniform1ui(programs_.refresh, 4, link_all ? 1 : 0);
  MLCLUST_RETURN_IF_ERROR(DispatchLinear(*context_, k_));
  gl.MemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  gl.UseProgram(0);
  std::swap(buffers_[kNeighboursIn], buffers_[kNeighboursOut]);
  return CheckGlError(*context_, kNeighboursPass);
}

absl::Status PointLevelsGpu::LinkAll() {
  MLCLUST_RETURN_IF_ERROR(BeginPass(*context_, kNeighboursPass));
  ++level_;  // no partner is this level's
  absl::Status linked = Refresh(/*link_all=*/true);
  if (!linked.ok()) return PassError(kNeighboursPass, linked);
  return absl::OkStatus();
}

absl::StatusOr<bool> PointLevelsGpu::Level(PmlPairRule rule, uint32_t clusters, uint32_t lowest,
                                           PointLevelGpu& level) {
  MLCLUST_ASSIGN_OR_RETURN(const bool merged, MergeLevel(rule, clusters, lowest, level));
  if (merged) MLCLUST_RETURN_IF_ERROR(RefreshNeighbours());
  return merged;
}

absl::StatusOr<bool> PointLevelsGpu::MergeLevel(PmlPairRule rule, uint32_t clusters,
                                                uint32_t lowest, PointLevelGpu& level) {
  level = PointLevelGpu();
  ++level_;
  return RunPmlLevelPasses(
      *context_, kLevelPasses, [&] { return FindPairs(); },
      [&](uint32_t pairs) { return Collapse(rule, clusters, lowest, pairs, level); },
      [&](uint32_t pairs) { return Extract(pairs, level); }, level);
}

absl::Status PointLevelsGpu::RefreshNeighbours() {
  MLCLUST_RETURN_IF_ERROR(BeginPass(*context_, kNeighboursPass));
  absl::Status refreshed = Refresh(/*link_all=*/false);
  if (!refreshed.ok()) return PassError(kNeighboursPass, refreshed);
  return absl::OkStatus();
}

LnKmeansResidentClusters PointLevelsGpu::Resident() const {
  return {&buffers_[kLabels], &buffers_[kCentroids], &buffers_[kNeighboursIn], &buffers_[kCounts]};
}

absl::Status PointLevelsGpu::Update(std::span<const uint32_t> clusters,
                                    std::span<const uint32_t> counts,
                                    std::span<const double> values,
                                    std::span<const uint32_t> points,
                                    std::span<const uint32_t> labels) {
  const uint64_t width = 2 * uint64_t{d_} + 1;
  if (counts.size() != clusters.size() || values.size() != clusters.size() * width ||
      labels.size() != points.size()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "points update: ", clusters.size(), " clusters with ", counts.size(), " counts and ",
        values.size(), " values, ", points.size(), " points with ", labels.size(), " labels"));
  }
  for (const uint32_t c : clusters) {
    if (c >= k_) return absl::InvalidArgumentError("points update: a cluster out of range");
  }
  for (size_t r = 0; r < points.size(); ++r) {
    if (points[r] >= m_ || labels[r] >= k_) {
      return absl::InvalidArgumentError("points update: a point or label out of range");
    }
  }
  const uint64_t entries = clusters.size() + points.size();
  if (entries == 0) return absl::OkStatus();
  MLCLUST_RETURN_IF_ERROR(BeginPass(*context_, kUpdatePass));
  absl::Status status = [&]() -> absl::Status {
    // Grown by doubling up to the largest update there can be (every cluster and every
    // point, UpdateStagingBytes), which PointLevelsMemoryBound counts.
    const std::array<uint64_t, 2> bytes = {8 * entries, 8 * std::max<uint64_t>(values.size(), 1)};
    const std::array<uint64_t, 2> most = UpdateStagingBytes(m_, k_, d_);
    for (size_t b = 0; b < 2; ++b) {
      const bool have = staging_.size() > b;
      if (have && staging_[b].bytes() >= bytes[b]) continue;
      const uint64_t size =
          std::max(bytes[b], std::min(most[b], have ? 2 * staging_[b].bytes() : 0));
      MLCLUST_ASSIGN_OR_RETURN(StorageBuffer buffer, StorageBuffer::Create(*context_, size));
      if (have) {
        staging_[b] = std::move(buffer);
      } else {
        staging_.push_back(std::move(buffer));
      }
    }
    std::vector<uint32_t> ids;
    ids.reserve(2 * entries);
    ids.insert(ids.end(), clusters.begin(), clusters.end());
    ids.insert(ids.end(), counts.begin(), counts.end());
    ids.insert(ids.end(), points.begin(), points.end());
    ids.insert(ids.end(), labels.begin(), labels.end());
    MLCLUST_RETURN_IF_ERROR(staging_[0].Upload(std::span<const uint32_t>(ids)));
    if (!values.empty()) MLCLUST_RETURN_IF_ERROR(staging_[1].Upload(values));
    const detail::GlFunctions& gl = context_->gl();
    BindAll();
    staging_[0].Bind(kPairIds);
    staging_[1].Bind(kPairValues);
    gl.UseProgram(programs_.update);
    gl.ProgramUniform1ui(programs_.update, 0, static_cast<uint32_t>(clusters.size()));
    gl.ProgramUniform1ui(programs_.update, 1, static_cast<uint32_t>(points.size()));
    gl.ProgramUniform1ui(programs_.update, 2, d_);
    MLCLUST_RETURN_IF_ERROR(DispatchLinear(*context_, entries));
    gl.MemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    gl.UseProgram(0);
    BindAll();
    return CheckGlError(*context_, kUpdatePass);
  }();
  return PassError(kUpdatePass, status);
}

absl::Status PointLevelsGpu::HcPhase(
    uint32_t phase, uint64_t invocations,
    std::initializer_list<std::pair<uint32_t, uint32_t>> uniforms) {
  const detail::GlFunctions& gl = context_->gl();
  gl.UseProgram(programs_.hc);
  gl.ProgramUniform1ui(programs_.hc, 0, k_);
  gl.ProgramUniform1ui(programs_.hc, 1, phase);
  gl.ProgramUniform1ui(programs_.hc, 2, d_);
  for (const auto& [location, value] : uniforms) {
    gl.ProgramUniform1ui(programs_.hc, location, value);
  }
  absl::Status dispatched = DispatchLinear(*context_, invocations);
  if (dispatched.ok()) gl.MemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  gl.UseProgram(0);
  return dispatched;
}

absl::Status PointLevelsGpu::CommitOdes(bool all) {
  MLCLUST_RETURN_IF_ERROR(BeginPass(*context_, kHcOdesPass));
  absl::Status status = [&]() -> absl::Status {
    BindAll();
    // Not all: the fresh ODEs of the flagged clusters only (points_ode.glsl's u_needed_at,
    // the flags' offset in the work buffer), those whose stored partner is gone included.
    if (!all) MLCLUST_RETURN_IF_ERROR(HcPhase(kHcNeeded, k_));
    context_->gl().ProgramUniform1ui(programs_.ode, kOdeNeededAt,
                                     all ? 0u : static_cast<uint32_t>(4 + 4 * uint64_t{k_}));
    const absl::Status found =
        FindOdes(*context_, {programs_.ode, 0, k_, k_ * 2 * d_, d_, kHcOdesPass});
    // Back to every edge whatever happened (the program is cached per context; FindPairs
    // sets it too).
    context_->gl().ProgramUniform1ui(programs_.ode, kOdeNeededAt, 0);
    MLCLUST_RETURN_IF_ERROR(found);
    MLCLUST_RETURN_IF_ERROR(HcPhase(kHcCommit, k_, {{8, all ? 1u : 0u}}));
    return CheckGlError(*context_, kHcOdesPass);
  }();
  return PassError(kHcOdesPass, status);
}

absl::Status PointLevelsGpu::StartSteps() {
  if (k_ == 0) return absl::OkStatus();
  return CommitOdes(/*all=*/true);
}

absl::StatusOr<bool> PointLevelsGpu::StepMerge(PointLevelGpu& level, uint32_t& keep, uint32_t& gone,
                                               uint32_t& size) {
  level = PointLevelGpu();
  if (k_ == 0) return false;
  ++level_;
  MLCLUST_RETURN_IF_ERROR(BeginPass(*context_, kHcSelectPass));
  // The work's state: listed, repaired, the chosen cluster, its partner.
  std::array<uint32_t, 4> state{};
  absl::Status selected = [&]() -> absl::Status {
    const detail::GlFunctions& gl = context_->gl();
    // As the CPU's queue pops (OdeHeap::PopCheapest, then SequentialMerge): the cheapest
    // stored ODE; where its partner is gone, that ODE recomputed and the next cheapest.
    // Each repeat recomputes one cluster's ODE, so there are at most k of them.
    for (uint32_t repeat = 0; repeat <= k_; ++repeat) {
      BindAll();
      buffers_[kCounts].Bind(1);      // ml_min_ode.glsl's sizes
      buffers_[kStoredOdes].Bind(7);  // its ODEs: the stored ones
      gl.UseProgram(programs_.min_ode);
      gl.ProgramUniform1ui(programs_.min_ode, 0, k_);
      gl.ProgramUniform1ui(programs_.min_ode, 1, 0);
      MLCLUST_RETURN_IF_ERROR(DispatchLinear(*context_, 1));  // one work group
      gl.MemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
      gl.UseProgram(0);
      BindAll();
      MLCLUST_RETURN_IF_ERROR(HcPhase(kHcRepair, 1));
      MLCLUST_RETURN_IF_ERROR(buffers_[kHcWork].Download(std::span<uint32_t>(state)));
      MLCLUST_RETURN_IF_ERROR(CheckGlError(*context_, kHcSelectPass));
      if (state[1] == 0) return absl::OkStatus();
    }
    return absl::InternalError("the stored ODEs kept naming gone partners");
  }();
  MLCLUST_RETURN_IF_ERROR(PassError(kHcSelectPass, selected));
  if (state[2] == kNone) return false;
  if (state[2] >= k_ || state[3] >= k_) {
    return PassError(kHcSelectPass,
                     absl::InternalError(absl::StrCat("the cheapest ODE joins clusters ", state[2],
                                                      " and ", state[3], " of ", k_)));
  }
  const uint32_t a = state[2], b = state[3];
  // The one pair (pair 0, written by ml_min_ode.glsl) through the merge pass, its energy
  // changes read back (ReadLevelTriplets' sum, without triplets), and which cluster kept
  // its id and its size (points_hc.glsl phase 8).
  MLCLUST_RETURN_IF_ERROR(BeginPass(*context_, kCollapsePass));
  const absl::Status merged = [&]() -> absl::Status {
    const detail::GlFunctions& gl = context_->gl();
    gl.ProgramUniform1ui(programs_.merge, 2, d_);
    gl.ProgramUniform1ui(programs_.merge, 3, level_);
    MLCLUST_RETURN_IF_ERROR(
        DispatchPairMerge(*context_, programs_.merge, /*pairs=*/1, /*use_flags=*/false));
    MLCLUST_RETURN_IF_ERROR(HcPhase(kHcMerged, 1));
    // The state, then the two energy changes' bits (the touched list's place, free here).
    std::array<uint32_t, 8> merged_state{};
    MLCLUST_RETURN_IF_ERROR(buffers_[kHcWork].Download(std::span<uint32_t>(merged_state)));
    std::copy_n(merged_state.begin(), 4, state.begin());
    if (!((state[2] == a && state[3] == b) || (state[2] == b && state[3] == a))) {
      return absl::InternalError(absl::StrCat("the merge of ", a, " and ", b, " kept ", state[2],
                                              " and removed ", state[3]));
    }
    keep = state[2];
    gone = state[3];
    size = state[1];
    std::array<double, 2> values{};
    std::memcpy(values.data(), &merged_state[4], sizeof(values));
    ::mlclust::detail::CompensatedSum change;
    change.Add(values[0]);
    change.Add(values[1]);
    level.energy_change = change.value();
    level.merged = 1;
    return CheckGlError(*context_, kCollapsePass);
  }();
  MLCLUST_RETURN_IF_ERROR(PassError(kCollapsePass, merged));
  return true;
}

absl::Status PointLevelsGpu::StepRefresh(uint32_t keep, uint32_t gone,
                                         std::span<const uint32_t> touched,
                                         std::vector<uint32_t>* rows) {
  if (keep >= k_ || gone >= k_ || touched.size() > k_) {
    return absl::InvalidArgumentError(absl::StrCat("points hc: merge ", keep, " <- ", gone, " or ",
                                                   touched.size(),
                                                   " touched clusters out of range for ", k_));
  }
  for (const uint32_t c : touched) {
    if (c >= k_) return absl::InvalidArgumentError("points hc: a touched cluster out of range");
  }
  MLCLUST_RETURN_IF_ERROR(BeginPass(*context_, kHcNeighboursPass));
  absl::Status status = [&]() -> absl::Status {
    std::vector<uint32_t> head(4 + touched.size(), 0);
    std::copy(touched.begin(), touched.end(), head.begin() + 4);
    MLCLUST_RETURN_IF_ERROR(buffers_[kHcWork].Upload(std::span<const uint32_t>(head)));
    BindAll();
    const auto count = static_cast<uint32_t>(touched.size());
    const std::initializer_list<std::pair<uint32_t, uint32_t>> step = {
        {3, count}, {4, keep}, {5, gone}};
    MLCLUST_RETURN_IF_ERROR(HcPhase(kHcPlaces, count, step));
    MLCLUST_RETURN_IF_ERROR(HcPhase(kHcMark, k_, step));
    uint32_t listed = 0;
    MLCLUST_RETURN_IF_ERROR(buffers_[kHcWork].Download(std::span<uint32_t>(&listed, 1)));
    if (listed > k_) return absl::InternalError("points hc: more clusters listed than there are");
    if (listed > 0) MLCLUST_RETURN_IF_ERROR(HcPhase(kHcOrder, listed, step));
    // One refresh offers the merged cluster, the gone one's 2d neighbours, its own and
    // theirs (about 2d + 1 iterations each), and where none is left every cluster (at most
    // once in a dispatch in practice; the stage refuses k0 (2d + 1) over the budget).
    uint32_t chunk = std::max(listed, 1u);
    if (context_->is_software()) {
      const uint64_t slots = 2 * uint64_t{d_}, offer = 2 * uint64_t{d_} + 1;
      const uint64_t one = (1 + slots + slots * (slots + 1)) * offer;
      const uint64_t all = uint64_t{k_} * offer;
      const uint64_t left = kPointsSoftwareLoopBudget > all ? kPointsSoftwareLoopBudget - all : 0;
      chunk = static_cast<uint32_t>(std::max<uint64_t>(1, left / one));
    }
    for (uint32_t begin = 0; begin < listed; begin += chunk) {
      const uint32_t end = std::min(listed, begin + chunk);
      MLCLUST_RETURN_IF_ERROR(
          HcPhase(kHcRefresh, 1, {{3, count}, {4, keep}, {5, gone}, {6, begin}, {7, end}}));
    }
    MLCLUST_RETURN_IF_ERROR(HcPhase(kHcFinish, 1, step));
    if (rows != nullptr) {
      // The refreshed clusters in order, then their rows and the gone one's.
      const uint64_t slots = 2 * uint64_t{d_};
      rows->assign(listed + 1 + (uint64_t{listed} + 1) * slots, 0);
      if (listed > 0) {
        MLCLUST_RETURN_IF_ERROR(buffers_[kHcWork].Download(
            std::span<uint32_t>(rows->data(), listed), (4 + 2 * uint64_t{k_}) * 4));
      }
      (*rows)[listed] = gone;
      MLCLUST_RETURN_IF_ERROR(HcPhase(kHcGather, uint64_t{listed} + 1, step));
      MLCLUST_RETURN_IF_ERROR(buffers_[kHcWork].Download(
          std::span<uint32_t>(rows->data() + listed + 1, (uint64_t{listed} + 1) * slots),
          (4 + 5 * uint64_t{k_}) * 4));
    }
    return CheckGlError(*context_, kHcNeighboursPass);
  }();
  MLCLUST_RETURN_IF_ERROR(PassError(kHcNeighboursPass, status));
  return CommitOdes(/*all=*/false);
}

absl::StatusOr<std::vector<uint32_t>> PointLevelsGpu::Labels() {
  std::vector<uint32_t> labels(m_);
  if (m_ > 0) MLCLUST_RETURN_IF_ERROR(ReadBack(kLabels, std::span<uint32_t>(labels)));
  return labels;
}

absl::StatusOr<std::vector<uint32_t>> PointLevelsGpu::Neighbours() {
  std::vector<uint32_t> table(size_t{k_} * 2 * d_);
  if (k_ > 0) MLCLUST_RETURN_IF_ERROR(ReadBack(kNeighboursIn, std::span<uint32_t>(table)));
  return table;
}

absl::Status PointLevelsGpu::ReadBack(uint32_t binding, std::span<uint32_t> out) {
  MLCLUST_RETURN_IF_ERROR(BeginPass(*context_, kReadBackPass));
  absl::Status status = buffers_[binding].Download(out);
  if (status.ok()) status = CheckGlError(*context_, kReadBackPass);
  return PassError(kReadBackPass, status);
}

}  // namespace mlclust::gpu
