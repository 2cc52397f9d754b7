#include "gpu/kernels/pml_levels.h"

#include <algorithm>
#include <array>
#include <functional>
#include <optional>

#include "absl/strings/str_cat.h"
#include "core/base/status_macros.h"
#include "gpu/context/gl_functions.h"
#include "gpu/context/pass.h"
#include "gpu/kernels/ml_min_ode_glsl.h"    // kMlMinOdeGlsl, generated
#include "gpu/kernels/mutual_pairs_glsl.h"  // kMutualPairsGlsl, generated
#include "gpu/kernels/pair_merge_glsl.h"    // kPairMergeGlsl, generated
#include "gpu/kernels/pml_bb_glsl.h"        // kPmlBbGlsl, generated
#include "gpu/kernels/pml_cvd_glsl.h"       // kPmlCvdGlsl, generated
#include "gpu/kernels/pml_merge_glsl.h"     // kPmlMergeGlsl, generated
#include "gpu/kernels/pml_pair_selection.h"
#include "gpu/kernels/pml_pairs_glsl.h"  // kPmlPairsGlsl, generated

namespace mlclust::gpu {
namespace {

constexpr char kOdesPass[] = "pml odes";
constexpr char kCollapsePass[] = "pml collapse";
constexpr char kTripletsPass[] = "pml triplets";
constexpr PmlLevelPasses kLevelPasses{kOdesPass, kCollapsePass, kTripletsPass};
constexpr char kBbDecidePass[] = "pml bb decide";
constexpr char kBbApplyPass[] = "pml bb apply";
constexpr char kBbEdgesPass[] = "pml bb edges";
constexpr char kMinOdePass[] = "ml min ode";
constexpr uint32_t kNoCluster = 0xFFFFFFFFu;

// pml_compact.glsl's kinds and counter slots.
constexpr uint32_t kFaces = 0, kEdges = 1, kFaceEdgeList = 2;
// pml_bb.glsl's phases.
constexpr uint32_t kFitProxies = 0, kWriteLabels = 1, kWriteClusters = 2;
constexpr uint32_t kPairSlot = 0, kTripletSlot = 1, kEdgeSlot = 2, kCounterSlots = 4;
// FindMutualPairs (pml_pair_selection.h) zeroes 4 counter slots and reads the pairs' slot 0;
// pml_compact.glsl writes (not adds to) the others, so Step, which skips it, needs no zeroing.
static_assert(kPairSlot == 0 && kCounterSlots == 4);

static_assert(sizeof(CvdSums) == 5 * sizeof(double));

uint64_t MaxPairs(uint64_t num_faces) { return num_faces / 2 + 1; }
uint64_t ChangeSlots(uint64_t num_faces) {
  return std::min<uint64_t>(std::max<uint64_t>(num_faces, 1), kPmlBbChangeChunk);
}

// The directed face edges (f, g) of `adjacency`, f's edges in f's order, faces in order.
absl::StatusOr<std::vector<uint32_t>> DirectedFaceEdges(const FaceAdjacency& adjacency) {
  const size_t n = adjacency.num_faces();
  std::vector<uint32_t> edges;
  edges.reserve(6 * n);
  for (size_t f = 0; f < n; ++f) {
    for (const FaceId g : adjacency.neighbours[f]) {
      if (!g.valid() || g.value() == f) continue;
      if (g.value() >= n) {
        return absl::InvalidArgumentError(
            absl::StrCat("pml: face ", f, " has neighbour ", g.value(), " of ", n, " faces"));
      }
      edges.push_back(static_cast<uint32_t>(f));
      edges.push_back(g.value());
    }
  }
  return edges;
}

}  // namespace

uint64_t PmlBoundaryMemoryBound(uint64_t num_faces, uint64_t num_edges) {
  const uint64_t n = std::max<uint64_t>(num_faces, 1), m = std::max<uint64_t>(num_edges, 1);
  return m * 8 + n * (12 + 32 + 32 + 8) + 4 + ChangeSlots(n) * (8 + 8 + 40);
}

uint64_t PmlLevelsMemoryBound(uint64_t num_faces, uint64_t num_edges) {
  const uint64_t n = std::max<uint64_t>(num_faces, 1), m = std::max<uint64_t>(num_edges, 1);
  const uint64_t chunks = std::max(PmlChunks(n), PmlChunks(m)),
                 groups = std::max(PmlGroups(n), PmlGroups(m));
  return n * (40 + 12 + 12 + 12) + 3 * m * 8 + MaxPairs(n) * (8 + 24 + 4) + chunks * 4 +
         groups * 4 + kCounterSlots * 4;
}

absl::StatusOr<PmlLevelsGpu> PmlLevelsGpu::Create(GlContext& context,
                                                  std::span<const CvdSums> face_sums,
                                                  const FaceAdjacency& adjacency) {
  const size_t n = adjacency.num_faces();
  if (face_sums.size() != n) {
    return absl::InvalidArgumentError(
        absl::StrCat("pml: ", face_sums.size(), " face sums for ", n, " faces"));
  }
  // Shader indices are 32-bit: 2 * edge (3 edges per face at most), 5 * cluster, 3 * face.
  if (n > kMaxMeshElements / 6) {
    return absl::InvalidArgumentError(
        absl::StrCat("pml: ", n, " faces exceed the limit of ", kMaxMeshElements / 6));
  }
  MLCLUST_ASSIGN_OR_RETURN(const std::vector<uint32_t> edges, DirectedFaceEdges(adjacency));
  const uint64_t m = edges.size() / 2;
  MLCLUST_RETURN_IF_ERROR(BeginPass(context, kOdesPass));
  absl::StatusOr<PmlLevelsGpu> made = [&]() -> absl::StatusOr<PmlLevelsGpu> {
    const uint64_t faces = std::max<uint64_t>(n, 1), edge_slots = std::max<uint64_t>(m, 1);
    const uint64_t chunks = std::max(PmlChunks(faces), PmlChunks(edge_slots));
    const uint64_t groups = std::max(PmlGroups(faces), PmlGroups(edge_slots));
    const std::array<uint64_t, kBindings> bytes = {
        faces * 40,      faces * 4,      faces * 4,  faces * 4,         edge_slots * 8,
        edge_slots * 8,  edge_slots * 8, faces * 12, MaxPairs(n) * 8,   MaxPairs(n) * 24,
        MaxPairs(n) * 4, chunks * 4,     groups * 4, kCounterSlots * 4, faces * 12};
    MLCLUST_ASSIGN_OR_RETURN(std::vector<StorageBuffer> buffers,
                             CreateStorageBuffers(context, bytes));
    std::vector<uint32_t> ones(n, 1), identity(n);
    for (uint32_t f = 0; f < n; ++f) identity[f] = f;
    if (n > 0) {
      MLCLUST_RETURN_IF_ERROR(buffers[kSums].Upload(0, face_sums.data(), face_sums.size_bytes()));
      MLCLUST_RETURN_IF_ERROR(buffers[kSizes].Upload(std::span<const uint32_t>(ones)));
      MLCLUST_RETURN_IF_ERROR(buffers[kLabels].Upload(std::span<const uint32_t>(identity)));
      MLCLUST_RETURN_IF_ERROR(buffers[kRemap].Upload(std::span<const uint32_t>(identity)));
    }
    if (m > 0) MLCLUST_RETURN_IF_ERROR(buffers[kEdgesIn].Upload(std::span<const uint32_t>(edges)));
    Programs programs;
    const std::string prelude = absl::StrCat(kComputeShaderPrelude, kPmlCvdGlsl);
    MLCLUST_ASSIGN_OR_RETURN(programs.ode, GetPmlOdeProgram(context));
    MLCLUST_ASSIGN_OR_RETURN(
        programs.pairs, GetComputeProgram(context, "pml_pairs",
                                          absl::StrCat(prelude, kPmlPairsGlsl, kMutualPairsGlsl)));
    MLCLUST_ASSIGN_OR_RETURN(
        programs.merge, GetComputeProgram(context, "pml_merge",
                                          absl::StrCat(prelude, kPmlMergeGlsl, kPairMergeGlsl)));
    MLCLUST_ASSIGN_OR_RETURN(programs.compact, GetPmlCompactProgram(context));
    MLCLUST_RETURN_IF_ERROR(CheckGlError(context, kOdesPass));
    return PmlLevelsGpu(context, static_cast<uint32_t>(n), static_cast<uint32_t>(m), programs,
                        std::move(buffers));
  }();
  if (!made.ok()) return PassError(kOdesPass, made.status());
  return made;
}

void PmlLevelsGpu::BindAll() {
  for (uint32_t b = 0; b < kBindings; ++b) buffers_[b].Bind(b);
}

absl::StatusOr<uint32_t> PmlLevelsGpu::FindPairs() {
  BindAll();
  return FindMutualPairs(
      *context_, buffers_[kCounters],
      {programs_.ode, programs_.pairs, num_faces_, num_edges_, std::nullopt, kOdesPass});
}

absl::Status PmlLevelsGpu::Collapse(PmlPairRule rule, uint32_t clusters, uint32_t lowest,
                                    uint32_t pairs, PmlLevelGpu& level) {
  MLCLUST_RETURN_IF_ERROR(MergeSelectedPairs(*context_, programs_.merge, rule, clusters, lowest,
                                             pairs, buffers_[kPairIds], buffers_[kPairValues],
                                             buffers_[kPairSelected], level.merged));
  return CheckGlError(*context_, kCollapsePass);
}

absl::Status PmlLevelsGpu::Compact(uint32_t kind, uint32_t count, uint32_t slot) {
  return CompactInOrder(*context_, programs_.compact, kind, count, buffers_[kCounters], slot);
}

absl::Status PmlLevelsGpu::Extract(uint32_t pairs, PmlLevelGpu& level) {
  MLCLUST_RETURN_IF_ERROR(Compact(kFaces, num_faces_, kTripletSlot));
  MLCLUST_RETURN_IF_ERROR(Compact(kEdges, num_edges_, kEdgeSlot));
  std::array<uint32_t, kCounterSlots> counters{};
  MLCLUST_RETURN_IF_ERROR(buffers_[kCounters].Download(std::span<uint32_t>(counters)));
  std::swap(buffers_[kEdgesIn], buffers_[kEdgesOut]);
  num_edges_ = counters[kEdgeSlot];
  MLCLUST_RETURN_IF_ERROR(ReadLevelTriplets(counters[kTripletSlot], pairs, buffers_[kTriplets],
                                            buffers_[kPairValues], level));
  return CheckGlError(*context_, kTripletsPass);
}

absl::StatusOr<uint32_t> PmlLevelsGpu::StartLevel(PmlLevelGpu& level) {
  level = PmlLevelGpu();
  proxies_current_ = false;  // the merges change sums
  return RunOdesPass(
      *context_, kLevelPasses, [&] { return FindPairs(); }, level);
}

absl::Status PmlLevelsGpu::FinishLevel(const std::function<absl::Status()>& collapse,
                                       uint32_t pairs, PmlLevelGpu& level) {
  return RunCollapsePasses(*context_, kLevelPasses, collapse,
                           [&] { return Extract(pairs, level); });
}

absl::StatusOr<bool> PmlLevelsGpu::Level(PmlPairRule rule, uint32_t clusters, uint32_t lowest,
                                         PmlLevelGpu& level) {
  MLCLUST_ASSIGN_OR_RETURN(const uint32_t pairs, StartLevel(level));
  if (pairs == 0) return false;
  MLCLUST_RETURN_IF_ERROR(
      FinishLevel([&] { return Collapse(rule, clusters, lowest, pairs, level); }, pairs, level));
  return true;
}

absl::StatusOr<bool> PmlLevelsGpu::Step(bool ties_to_fewest_faces, PmlLevelGpu& level) {
  level = PmlLevelGpu();
  proxies_current_ = false;  // the merge changes sums
  // Every cluster's ODE only: ML has no use for the mutual pairs (nor their count).
  MLCLUST_RETURN_IF_ERROR(BeginPass(*context_, kOdesPass));
  BindAll();
  const absl::Status odes =
      FindOdes(*context_, {programs_.ode, 0, num_faces_, num_edges_, std::nullopt, kOdesPass});
  MLCLUST_RETURN_IF_ERROR(
      PassError(kOdesPass, odes.ok() ? CheckGlError(*context_, kOdesPass) : odes));
  MLCLUST_RETURN_IF_ERROR(BeginPass(*context_, kMinOdePass));
  std::array<uint32_t, 2> pair{};
  const absl::Status chosen = [&]() -> absl::Status {
    const detail::GlFunctions& gl = context_->gl();
    if (programs_.min_ode == 0) {
      MLCLUST_ASSIGN_OR_RETURN(
          programs_.min_ode, GetComputeProgram(*context_, "ml_min_ode",
                                               absl::StrCat(kComputeShaderPrelude, kMlMinOdeGlsl)));
    }
    gl.UseProgram(programs_.min_ode);
    gl.ProgramUniform1ui(programs_.min_ode, 0, num_faces_);
    gl.ProgramUniform1ui(programs_.min_ode, 1, ties_to_fewest_faces ? 1u : 0u);
    MLCLUST_RETURN_IF_ERROR(DispatchLinear(*context_, 1));  // one work group
    gl.MemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_BUFFER_UPDATE_BARRIER_BIT);
    gl.UseProgram(0);
    MLCLUST_RETURN_IF_ERROR(buffers_[kPairIds].Download(std::span<uint32_t>(pair)));
    MLCLUST_RETURN_IF_ERROR(CheckGlError(*context_, kMinOdePass));
    if (pair[0] != kNoCluster && (pair[0] >= num_faces_ || pair[1] >= num_faces_)) {
      return absl::InternalError(absl::StrCat("the GPU's cheapest ODE joins clusters ", pair[0],
                                              " and ", pair[1], " of ", num_faces_));
    }
    return absl::OkStatus();
  }();
  if (!chosen.ok()) return PassError(kMinOdePass, chosen);
  if (pair[0] == kNoCluster) return false;  // one cluster per component
  // The one pair (pair 0, written by ml_min_ode.glsl) through the merge pass, no flags.
  MLCLUST_RETURN_IF_ERROR(FinishLevel(
      [&]() -> absl::Status {
        MLCLUST_RETURN_IF_ERROR(
            DispatchPairMerge(*context_, programs_.merge, /*pairs=*/1, /*use_flags=*/false));
        level.merged = 1;
        return CheckGlError(*context_, kCollapsePass);
      },
      1, level));
  return true;
}

absl::StatusOr<std::vector<uint32_t>> PmlLevelsGpu::Labels() {
  std::vector<uint32_t> labels(num_faces_);
  if (num_faces_ > 0) {
    MLCLUST_RETURN_IF_ERROR(buffers_[kLabels].Download(std::span<uint32_t>(labels)));
  }
  return labels;
}

absl::Status PmlLevelsGpu::EnableBoundaryOptimisation(const FaceAdjacency& adjacency,
                                                      std::span<const PointAndWeight> faces) {
  const size_t n = adjacency.num_faces();
  if (n != num_faces_ || faces.size() != n) {
    return absl::InvalidArgumentError(absl::StrCat("pml bb: ", n, " faces of adjacency and ",
                                                   faces.size(), " face points for ", num_faces_,
                                                   " faces"));
  }
  MLCLUST_ASSIGN_OR_RETURN(const std::vector<uint32_t> edges, DirectedFaceEdges(adjacency));
  MLCLUST_RETURN_IF_ERROR(BeginPass(*context_, kBbDecidePass));
  const absl::Status status = [&]() -> absl::Status {
    const uint64_t faces_or_one = std::max<uint64_t>(n, 1);
    const uint64_t slots = ChangeSlots(n);
    const std::array<uint64_t, kBoundaryBuffers> bytes = {std::max<uint64_t>(edges.size(), 2) * 4,
                                                          faces_or_one * 12,
                                                          faces_or_one * 32,
                                                          faces_or_one * 32,
                                                          faces_or_one * 8,
                                                          4,
                                                          slots * 8,
                                                          slots * 8,
                                                          slots * 40};
    MLCLUST_ASSIGN_OR_RETURN(std::vector<StorageBuffer> buffers,
                             CreateStorageBuffers(*context_, bytes));
    if (!edges.empty()) {
      MLCLUST_RETURN_IF_ERROR(buffers[kFaceEdges].Upload(std::span<const uint32_t>(edges)));
    }
    if (n > 0) {
      MLCLUST_RETURN_IF_ERROR(buffers[kNeighbours].Upload(
          std::span<const std::array<FaceId, 3>>(adjacency.neighbours)));
      MLCLUST_RETURN_IF_ERROR(buffers[kFacePoints].Upload(faces));
    }
    MLCLUST_ASSIGN_OR_RETURN(bb_program_, GetComputeProgram(*context_, "pml_bb",
                                                            absl::StrCat(kComputeShaderPrelude,
                                                                         kPmlCvdGlsl, kPmlBbGlsl)));
    MLCLUST_RETURN_IF_ERROR(CheckGlError(*context_, kBbDecidePass));
    bb_buffers_ = std::move(buffers);
    num_face_edges_ = static_cast<uint32_t>(edges.size() / 2);
    return absl::OkStatus();
  }();
  return PassError(kBbDecidePass, status);
}

void PmlLevelsGpu::BindBbBuffers() {
  buffers_[kSums].Bind(0);
  buffers_[kSizes].Bind(1);
  buffers_[kLabels].Bind(2);
  bb_buffers_[kProxies].Bind(3);
  bb_buffers_[kLabelChanges].Bind(4);
  bb_buffers_[kClusterChanges].Bind(5);
  bb_buffers_[kClusterSums].Bind(6);
}

absl::Status PmlLevelsGpu::Decide(std::vector<PmlFaceMove>& proposals) {
  proposals.clear();
  if (bb_buffers_.empty()) {
    return absl::FailedPreconditionError("pml bb: decide before EnableBoundaryOptimisation");
  }
  if (num_faces_ == 0) return absl::OkStatus();
  MLCLUST_RETURN_IF_ERROR(BeginPass(*context_, kBbDecidePass));
  const absl::Status status = [&]() -> absl::Status {
    const detail::GlFunctions& gl = context_->gl();
    if (!proxies_current_) {
      // The proxies of every cluster id; ApplyMoves keeps them.
      BindBbBuffers();
      gl.UseProgram(bb_program_);
      gl.ProgramUniform1ui(bb_program_, 0, num_faces_);
      gl.ProgramUniform1ui(bb_program_, 1, kFitProxies);
      MLCLUST_RETURN_IF_ERROR(DispatchLinear(*context_, num_faces_));
      gl.MemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    }
    MLCLUST_RETURN_IF_ERROR(DispatchBoundaryDecide(
        *context_, kBbDecidePass,
        {&bb_buffers_[kNeighbours], &buffers_[kLabels], &bb_buffers_[kFacePoints],
         &bb_buffers_[kProxies], &bb_buffers_[kProposals], &bb_buffers_[kProposalCount]},
        num_faces_, num_faces_, proposals));
    proxies_current_ = true;
    return absl::OkStatus();
  }();
  if (!status.ok()) {
    proposals.clear();
    proxies_current_ = false;
  }
  return PassError(kBbDecidePass, status);
}

absl::Status PmlLevelsGpu::ApplyMoves(std::span<const PmlFaceMove> moves,
                                      std::span<const PmlClusterChange> clusters) {
  if (bb_buffers_.empty()) {
    return absl::FailedPreconditionError("pml bb: moves before EnableBoundaryOptimisation");
  }
  for (const auto& [face, cluster] : moves) {
    if (face >= num_faces_ || cluster >= num_faces_) {
      return absl::InvalidArgumentError(
          absl::StrCat("pml bb: move of face ", face, " to ", cluster, " of ", num_faces_));
    }
  }
  for (const PmlClusterChange& change : clusters) {
    if (change.cluster >= num_faces_ || change.size > num_faces_) {
      return absl::InvalidArgumentError(absl::StrCat("pml bb: cluster ", change.cluster,
                                                     " of size ", change.size, " of ", num_faces_));
    }
  }
  MLCLUST_RETURN_IF_ERROR(BeginPass(*context_, kBbApplyPass));
  const absl::Status status = [&]() -> absl::Status {
    const detail::GlFunctions& gl = context_->gl();
    BindBbBuffers();
    gl.UseProgram(bb_program_);
    for (size_t begin = 0; begin < moves.size(); begin += kPmlBbChangeChunk) {
      const size_t count = std::min<size_t>(kPmlBbChangeChunk, moves.size() - begin);
      MLCLUST_RETURN_IF_ERROR(bb_buffers_[kLabelChanges].Upload(moves.subspan(begin, count)));
      gl.ProgramUniform1ui(bb_program_, 0, static_cast<uint32_t>(count));
      gl.ProgramUniform1ui(bb_program_, 1, kWriteLabels);
      MLCLUST_RETURN_IF_ERROR(DispatchLinear(*context_, count));
      gl.MemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_BUFFER_UPDATE_BARRIER_BIT);
    }
    for (size_t begin = 0; begin < clusters.size(); begin += kPmlBbChangeChunk) {
      const size_t count = std::min<size_t>(kPmlBbChangeChunk, clusters.size() - begin);
      change_words_.resize(2 * count);
      change_sums_.resize(5 * count);
      for (size_t i = 0; i < count; ++i) {
        const PmlClusterChange& change = clusters[begin + i];
        change_words_[2 * i] = change.cluster;
        change_words_[2 * i + 1] = change.size;
        change_sums_[5 * i] = change.sums.area;
        change_sums_[5 * i + 1] = change.sums.weighted_centroid.x;
        change_sums_[5 * i + 2] = change.sums.weighted_centroid.y;
        change_sums_[5 * i + 3] = change.sums.weighted_centroid.z;
        change_sums_[5 * i + 4] = change.sums.weighted_squared_norm;
      }
      MLCLUST_RETURN_IF_ERROR(
          bb_buffers_[kClusterChanges].Upload(std::span<const uint32_t>(change_words_)));
      MLCLUST_RETURN_IF_ERROR(
          bb_buffers_[kClusterSums].Upload(std::span<const double>(change_sums_)));
      gl.ProgramUniform1ui(bb_program_, 0, static_cast<uint32_t>(count));
      gl.ProgramUniform1ui(bb_program_, 1, kWriteClusters);
      MLCLUST_RETURN_IF_ERROR(DispatchLinear(*context_, count));
      gl.MemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_BUFFER_UPDATE_BARRIER_BIT);
    }
    gl.UseProgram(0);
    return CheckGlError(*context_, kBbApplyPass);
  }();
  if (!status.ok()) proxies_current_ = false;
  return PassError(kBbApplyPass, status);
}

absl::Status PmlLevelsGpu::RebuildEdges() {
  if (bb_buffers_.empty()) {
    return absl::FailedPreconditionError("pml bb: edges before EnableBoundaryOptimisation");
  }
  MLCLUST_RETURN_IF_ERROR(BeginPass(*context_, kBbEdgesPass));
  const absl::Status status = [&]() -> absl::Status {
    BindAll();
    bb_buffers_[kFaceEdges].Bind(6);  // pml_compact.glsl's FaceEdges (kind 2)
    MLCLUST_RETURN_IF_ERROR(Compact(kFaceEdgeList, num_face_edges_, kEdgeSlot));
    uint32_t edges = 0;
    MLCLUST_RETURN_IF_ERROR(buffers_[kCounters].Download(kEdgeSlot * 4, &edges, 4));
    MLCLUST_RETURN_IF_ERROR(CheckGlError(*context_, kBbEdgesPass));
    if (edges > num_face_edges_) {
      return absl::InternalError(absl::StrCat("the GPU reports ", edges, " cluster edges of ",
                                              num_face_edges_, " face edges"));
    }
    std::swap(buffers_[kEdgesIn], buffers_[kEdgesOut]);
    num_edges_ = edges;
    return absl::OkStatus();
  }();
  return PassError(kBbEdgesPass, status);
}

}  // namespace mlclust::gpu
