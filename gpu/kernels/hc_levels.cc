#include "gpu/kernels/hc_levels.h"

#include <algorithm>
#include <array>
#include <string>

#include "absl/strings/str_cat.h"
#include "core/base/status_macros.h"
#include "gpu/context/gl_functions.h"
#include "gpu/context/pass.h"
#include "gpu/kernels/hc_common_glsl.h"  // kHcCommonGlsl, generated
#include "gpu/kernels/hc_init_glsl.h"    // kHcInitGlsl, generated
#include "gpu/kernels/hc_steps_glsl.h"   // kHcStepsGlsl, generated
#include "gpu/kernels/pml_cvd_glsl.h"    // kPmlCvdGlsl, generated (gpupml's)
#include "gpu/kernels/pml_pair_selection.h"

namespace mlclust::gpu {
namespace {

constexpr char kOdesPass[] = "hc odes";
constexpr char kCollapsePass[] = "hc collapse";
constexpr char kTripletsPass[] = "hc triplets";

constexpr uint32_t kNone = 0xFFFFFFFFu;
// The loop iterations (summed over the group's invocations) after which a batch ends on a
// software renderer: llvmpipe stops an invocation's loops after 65,535 in all
// (hc_steps.glsl), and the next step must still fit.
constexpr uint32_t kSoftwareLoopBudget = 24000;
// pml_ode.glsl's phases (gpu/kernels/pml_levels.cc).
constexpr uint32_t kPhaseCost = 0, kPhaseLow = 1, kPhasePartner = 2, kPhaseReset = 3;
// hc_init.glsl's phases.
constexpr uint32_t kInitOdes = 0, kInitTree = 1;
// hc_steps.glsl's control words.
constexpr uint32_t kLeft = 0, kBatchSteps = 1, kFacesUsed = 2, kAllSteps = 3, kLoopLimit = 4,
                   kControlWords = 5;

static_assert(sizeof(CvdSums) == 5 * sizeof(double));

// hc_common.glsl's Cluster.
struct ClusterRecord {
  uint32_t size, partner, stamp, ehead, etail, mhead, mtail, pad;
};
static_assert(sizeof(ClusterRecord) == 32);

uint64_t TreeNodes(uint64_t clusters) {
  uint64_t nodes = 0;
  do {
    clusters = (clusters + kHcTreeFanout - 1) / kHcTreeFanout;
    nodes += clusters;
  } while (clusters > 1);
  return nodes;
}
uint32_t TreeLevels(uint64_t clusters) {
  uint32_t levels = 0;
  while (clusters > 1 || levels == 0) {
    clusters = (clusters + kHcTreeFanout - 1) / kHcTreeFanout;
    ++levels;
  }
  return levels;
}
uint64_t LevelSize(uint64_t clusters, uint32_t level) {
  for (uint32_t l = 0; l < level; ++l) clusters = (clusters + kHcTreeFanout - 1) / kHcTreeFanout;
  return clusters;
}

// The steps' source: its own work group size instead of the prelude's.
std::string StepsSource(uint32_t group) {
  return absl::StrCat("#version 450 core\nlayout(local_size_x = ", group,
                      ", local_size_y = 1, local_size_z = 1) in;\n", kPmlCvdGlsl, kHcCommonGlsl,
                      kHcStepsGlsl);
}

}  // namespace

uint64_t HcLevelsMemoryBound(uint64_t num_faces, uint64_t num_edges) {
  const uint64_t n = std::max<uint64_t>(num_faces, 1), m = std::max<uint64_t>(num_edges, 1);
  return n * (40 + 32 + 8 + 4 + 4 + 4 + 4 + 12) + m * (8 + 4 + 8) + TreeNodes(n) * 8 + 2 * 4 +
         uint64_t{kHcMaxBatch} * sizeof(HcStepGpu) + kControlWords * 4;
}

absl::StatusOr<HcLevelsGpu> HcLevelsGpu::Create(GlContext& context,
                                                std::span<const CvdSums> face_sums,
                                                const FaceAdjacency& adjacency,
                                                bool ties_to_fewest_faces, uint32_t step_group) {
  const size_t n = adjacency.num_faces();
  if (face_sums.size() != n) {
    return absl::InvalidArgumentError(
        absl::StrCat("hc: ", face_sums.size(), " face sums for ", n, " faces"));
  }
  // Shader indices are 32-bit: 5 * cluster, and 2 * edge with up to 3 edges a face, so
  // 6 * faces must fit (as the PML kernels' kMaxMeshElements / 6).
  constexpr size_t kMaxFaces = size_t{0xFFFFFFFFu} / 6;
  if (n > kMaxFaces) {
    return absl::InvalidArgumentError(
        absl::StrCat("hc: ", n, " faces exceed the limit of ", kMaxFaces));
  }
  // The directed face edges grouped by face: face f's are one run, its list at the start.
  std::vector<uint32_t> edges;
  edges.reserve(6 * n);
  std::vector<ClusterRecord> records(n);
  std::vector<uint32_t> edge_next;
  edge_next.reserve(3 * n);
  for (size_t f = 0; f < n; ++f) {
    ClusterRecord& record = records[f];
    record = {1, kNone, 0, kNone, kNone, static_cast<uint32_t>(f), static_cast<uint32_t>(f), 0};
    for (const FaceId g : adjacency.neighbours[f]) {
      if (!g.valid() || g.value() == f) continue;
      if (g.value() >= n) {
        return absl::InvalidArgumentError(
            absl::StrCat("hc: face ", f, " has neighbour ", g.value(), " of ", n, " faces"));
      }
      const uint32_t e = static_cast<uint32_t>(edges.size() / 2);
      if (record.ehead == kNone) {
        record.ehead = e;
      } else {
        edge_next[record.etail] = e;
      }
      record.etail = e;
      edge_next.push_back(kNone);
      edges.push_back(static_cast<uint32_t>(f));
      edges.push_back(g.value());
    }
  }
  const uint64_t m = edges.size() / 2;
  MLCLUST_RETURN_IF_ERROR(BeginPass(context, kOdesPass));
  absl::StatusOr<HcLevelsGpu> made = [&]() -> absl::StatusOr<HcLevelsGpu> {
    const detail::GlFunctions& gl = context.gl();
    const uint64_t faces = std::max<uint64_t>(n, 1), edge_slots = std::max<uint64_t>(m, 1);
    const std::array<uint64_t, kBindings> bytes = {
        faces * 40,      faces * 32,
        faces * 8,       faces * 4,
        edge_slots * 8,  edge_slots * 4,
        edge_slots * 8,  faces * 12,
        faces * 4,       TreeNodes(faces) * 8,
        (faces + 2) * 4, uint64_t{kHcMaxBatch} * sizeof(HcStepGpu),
        faces * 4,       kControlWords * 4};
    MLCLUST_ASSIGN_OR_RETURN(std::vector<StorageBuffer> buffers,
                             CreateStorageBuffers(context, bytes));
    const uint32_t n32 = static_cast<uint32_t>(n);
    const std::array<uint32_t, kControlWords> control = {n32, 0, 0, 0, 0};
    MLCLUST_RETURN_IF_ERROR(buffers[kControl].Upload(std::span<const uint32_t>(control)));
    if (n > 0) {
      std::vector<uint32_t> identity(n), none(n, kNone);
      for (uint32_t f = 0; f < n; ++f) identity[f] = f;
      MLCLUST_RETURN_IF_ERROR(buffers[kSums].Upload(0, face_sums.data(), face_sums.size_bytes()));
      MLCLUST_RETURN_IF_ERROR(
          buffers[kClusters].Upload(0, records.data(), records.size() * sizeof(ClusterRecord)));
      MLCLUST_RETURN_IF_ERROR(buffers[kLabels].Upload(std::span<const uint32_t>(identity)));
      MLCLUST_RETURN_IF_ERROR(buffers[kMemberNext].Upload(std::span<const uint32_t>(none)));
    }
    if (m > 0) {
      MLCLUST_RETURN_IF_ERROR(buffers[kEdges].Upload(std::span<const uint32_t>(edges)));
      MLCLUST_RETURN_IF_ERROR(buffers[kEdgeNext].Upload(std::span<const uint32_t>(edge_next)));
    }
    const std::string cvd = absl::StrCat(kComputeShaderPrelude, kPmlCvdGlsl);
    // The ODE kernel of PML (pml_pair_selection.h).
    MLCLUST_ASSIGN_OR_RETURN(const uint32_t ode, GetPmlOdeProgram(context));
    MLCLUST_ASSIGN_OR_RETURN(
        const uint32_t init,
        GetComputeProgram(context, "hc_init", absl::StrCat(cvd, kHcCommonGlsl, kHcInitGlsl)));
    const uint32_t group = step_group != 0         ? step_group
                           : context.is_software() ? kHcSoftwareStepGroup
                                                   : kHcStepGroup;
    MLCLUST_ASSIGN_OR_RETURN(
        const uint32_t steps,
        GetComputeProgram(context, absl::StrCat("hc_steps_", group), StepsSource(group)));
    for (uint32_t b = 0; b < kBindings; ++b) buffers[b].Bind(b);
    if (n > 0) {
      gl.UseProgram(ode);
      gl.ProgramUniform1ui(ode, 0, n32);
      gl.ProgramUniform1ui(ode, 1, kPhaseReset);
      MLCLUST_RETURN_IF_ERROR(DispatchLinear(context, n));
      for (const uint32_t phase : {kPhaseCost, kPhaseLow, kPhasePartner}) {
        gl.MemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
        gl.ProgramUniform1ui(ode, 0, static_cast<uint32_t>(m));
        gl.ProgramUniform1ui(ode, 1, phase);
        MLCLUST_RETURN_IF_ERROR(DispatchLinear(context, m));
      }
      gl.MemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
      gl.UseProgram(init);
      gl.ProgramUniform1ui(init, 0, n32);
      gl.ProgramUniform1ui(init, 1, ties_to_fewest_faces ? 1u : 0u);
      gl.ProgramUniform1ui(init, 2, kInitOdes);
      MLCLUST_RETURN_IF_ERROR(DispatchLinear(context, n));
      gl.ProgramUniform1ui(init, 2, kInitTree);
      const uint32_t levels = TreeLevels(n);
      for (uint32_t level = 1; level <= levels; ++level) {
        gl.MemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
        gl.ProgramUniform1ui(init, 3, level);
        MLCLUST_RETURN_IF_ERROR(DispatchLinear(context, LevelSize(n, level)));
      }
      gl.MemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
      gl.UseProgram(0);
    }
    MLCLUST_RETURN_IF_ERROR(CheckGlError(context, kOdesPass));
    // The start's buffers are not needed any more.
    for (const Binding b : {kEdgeKeys, kOdes}) {
      MLCLUST_ASSIGN_OR_RETURN(buffers[b], StorageBuffer::Create(context, 4));
    }
    return HcLevelsGpu(context, n32, ties_to_fewest_faces, steps, std::move(buffers));
  }();
  if (!made.ok()) return PassError(kOdesPass, made.status());
  return made;
}

absl::Status HcLevelsGpu::Steps(uint32_t lowest, uint32_t max_steps, HcBatchGpu& batch) {
  batch.steps.clear();
  batch.faces.clear();
  max_steps = std::min(max_steps, kHcMaxBatch);
  if (num_faces_ < 2 || max_steps == 0) return absl::OkStatus();
  const detail::GlFunctions& gl = context_->gl();
  MLCLUST_RETURN_IF_ERROR(BeginPass(*context_, kCollapsePass));
  absl::Status collapsed = [&]() -> absl::Status {
    const std::array<uint32_t, 2> zeros{};
    MLCLUST_RETURN_IF_ERROR(
        buffers_[kControl].Upload(kBatchSteps * 4, zeros.data(), sizeof(zeros)));
    for (uint32_t b = 0; b < kBindings; ++b) buffers_[b].Bind(b);
    gl.UseProgram(steps_program_);
    gl.ProgramUniform1ui(steps_program_, 0, num_faces_);
    gl.ProgramUniform1ui(steps_program_, 1, tie_by_size_ ? 1u : 0u);
    gl.ProgramUniform1ui(steps_program_, 2, max_steps);
    gl.ProgramUniform1ui(steps_program_, 3, lowest);
    gl.ProgramUniform1ui(steps_program_, 4, num_faces_);
    gl.ProgramUniform1ui(steps_program_, 5, context_->is_software() ? kSoftwareLoopBudget : kNone);
    gl.ProgramUniform1ui(steps_program_, 6, 2);
    MLCLUST_RETURN_IF_ERROR(DispatchLinear(*context_, 1));
    gl.MemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    gl.UseProgram(0);
    return CheckGlError(*context_, kCollapsePass);
  }();
  if (!collapsed.ok()) return PassError(kCollapsePass, collapsed);
  MLCLUST_RETURN_IF_ERROR(BeginPass(*context_, kTripletsPass));
  bool loop_limit = false;
  absl::Status read = [&]() -> absl::Status {
    std::array<uint32_t, kControlWords> control{};
    MLCLUST_RETURN_IF_ERROR(buffers_[kControl].Download(std::span<uint32_t>(control)));
    loop_limit = control[kLoopLimit] != 0;
    batch.steps.resize(control[kBatchSteps]);
    batch.faces.resize(control[kFacesUsed]);
    if (!batch.steps.empty()) {
      MLCLUST_RETURN_IF_ERROR(buffers_[kStepLog].Download(0, batch.steps.data(),
                                                          batch.steps.size() * sizeof(HcStepGpu)));
    }
    if (!batch.faces.empty()) {
      MLCLUST_RETURN_IF_ERROR(buffers_[kLogFaces].Download(std::span<uint32_t>(batch.faces)));
    }
    return CheckGlError(*context_, kTripletsPass);
  }();
  if (!read.ok()) return PassError(kTripletsPass, read);
  if (loop_limit) {
    return PassError(kCollapsePass,
                     absl::InternalError(absl::StrCat(
                         "a step ran into the driver's limit of loop iterations per invocation (",
                         context_->renderer(), "): its clusters are too large for this driver")));
  }
  return absl::OkStatus();
}

absl::StatusOr<std::vector<uint32_t>> HcLevelsGpu::Labels() {
  std::vector<uint32_t> labels(num_faces_);
  if (num_faces_ > 0) {
    MLCLUST_RETURN_IF_ERROR(buffers_[kLabels].Download(std::span<uint32_t>(labels)));
  }
  return labels;
}

}  // namespace mlclust::gpu
