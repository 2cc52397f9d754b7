#include "gpu/kernels/voxel_start.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <span>
#include <string>
#include <utility>

#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"
#include "core/base/status_macros.h"
#include "core/points/points.h"
#include "gpu/context/compute.h"
#include "gpu/context/gl_functions.h"
#include "gpu/context/pass.h"
#include "gpu/kernels/compact_scan_glsl.h"  // kCompactScanGlsl, generated
#include "gpu/kernels/voxel_start_glsl.h"   // kVoxelStartGlsl, generated

namespace mlclust::gpu {
namespace {

constexpr char kPass[] = "voxel start";
constexpr uint32_t kBounds = 0, kInsert = 1, kCount = 2, kScan = 3, kTop = 4, kWrite = 5,
                   kLabel = 6, kNeighbours = 7;
constexpr uint32_t kChunk = 32, kGroup = 256, kBoundsBlock = 64;
constexpr uint32_t kNone = 0xFFFFFFFFu;

enum Binding : uint32_t {
  kPoints,
  kAxes,
  kBoundsBuffer,
  kPointSlot,
  kTable,
  kChunkCount,
  kGroupTotal,
  kCounters,
  kSlotCluster,
  kClusterFirst,
  kLabels,
  kNeighboursBuffer,
  kBindings
};

// voxel_start.glsl's Axis (std430: 16 bytes).
struct Axis {
  double span;
  float lo;
  uint32_t cells;
};
static_assert(sizeof(Axis) == 16);

uint64_t Chunks(uint64_t count) { return (count + kChunk - 1) / kChunk; }
uint64_t Groups(uint64_t count) { return (Chunks(count) + kGroup - 1) / kGroup; }
uint64_t Slots(uint64_t m) {
  uint64_t slots = 1;
  while (slots < 2 * std::max<uint64_t>(m, 1)) slots *= 2;
  return slots;
}

float FromKey(uint32_t key) {
  const uint32_t bits = (key & 0x80000000u) != 0 ? (key & 0x7FFFFFFFu) : ~key;
  float f;
  std::memcpy(&f, &bits, 4);
  return f;
}

class VoxelGrid {
 public:
  VoxelGrid(GlContext& context, uint32_t m, uint32_t d, uint32_t program,
            std::vector<StorageBuffer> buffers)
      : context_(context), m_(m), d_(d), program_(program), buffers_(std::move(buffers)) {}

  void BindAll() {
    for (uint32_t b = 0; b < kBindings; ++b) buffers_[b].Bind(b);
  }

  absl::Status Run(uint32_t phase, uint32_t count, uint64_t invocations) {
    const detail::GlFunctions& gl = context_.gl();
    gl.UseProgram(program_);
    gl.ProgramUniform1ui(program_, 0, count);
    gl.ProgramUniform1ui(program_, 1, phase);
    gl.ProgramUniform1ui(program_, 2, d_);
    gl.ProgramUniform1ui(program_, 3, static_cast<uint32_t>(Slots(m_) - 1));
    MLCLUST_RETURN_IF_ERROR(DispatchLinear(context_, invocations));
    gl.MemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    return absl::OkStatus();
  }

  // The box per axis: (lo, hi) as floats.
  absl::StatusOr<std::pair<std::vector<float>, std::vector<float>>> Bounds() {
    BindAll();
    std::vector<uint32_t> init(2 * d_);
    for (uint32_t j = 0; j < d_; ++j) {
      init[j] = 0xFFFFFFFFu;
      init[d_ + j] = 0;
    }
    MLCLUST_RETURN_IF_ERROR(buffers_[kBoundsBuffer].Upload(std::span<const uint32_t>(init)));
    MLCLUST_RETURN_IF_ERROR(Run(kBounds, m_, (uint64_t{m_} + kBoundsBlock - 1) / kBoundsBlock));
    MLCLUST_RETURN_IF_ERROR(buffers_[kBoundsBuffer].Download(std::span<uint32_t>(init)));
    std::vector<float> lo(d_), hi(d_);
    for (uint32_t j = 0; j < d_; ++j) {
      lo[j] = FromKey(init[j]);
      hi[j] = FromKey(init[d_ + j]);
    }
    return std::make_pair(std::move(lo), std::move(hi));
  }

  // Every point into the hash table at `cells` per axis; returns the occupied cells.
  absl::StatusOr<uint32_t> Insert(const std::vector<float>& lo, const std::vector<float>& hi,
                                  std::span<const uint32_t> cells) {
    std::vector<Axis> axes(d_);
    for (uint32_t j = 0; j < d_; ++j) {
      axes[j] = {static_cast<double>(hi[j]) - lo[j], lo[j], cells[j]};
    }
    MLCLUST_RETURN_IF_ERROR(buffers_[kAxes].Upload(std::span<const Axis>(axes)));
    const uint64_t slots = Slots(m_);
    std::vector<uint32_t> table(2 * slots);
    for (uint64_t s = 0; s < slots; ++s) {
      table[2 * s] = 0;
      table[2 * s + 1] = kNone;
    }
    MLCLUST_RETURN_IF_ERROR(buffers_[kTable].Upload(std::span<const uint32_t>(table)));
    const std::array<uint32_t, 4> zeros{};
    MLCLUST_RETURN_IF_ERROR(buffers_[kCounters].Upload(std::span<const uint32_t>(zeros)));
    BindAll();
    MLCLUST_RETURN_IF_ERROR(Run(kInsert, m_, m_));
    std::array<uint32_t, 4> counters{};
    MLCLUST_RETURN_IF_ERROR(buffers_[kCounters].Download(std::span<uint32_t>(counters)));
    MLCLUST_RETURN_IF_ERROR(CheckGlError(context_, kPass));
    return counters[1];
  }

  // After Insert: labels, clusters and their face-sharing neighbours.
  absl::Status Finish(VoxelStartGpuResult& result) {
    BindAll();
    const uint64_t chunks = Chunks(m_), groups = Groups(m_);
    MLCLUST_RETURN_IF_ERROR(Run(kCount, m_, chunks));
    MLCLUST_RETURN_IF_ERROR(Run(kScan, static_cast<uint32_t>(chunks), groups));
    MLCLUST_RETURN_IF_ERROR(Run(kTop, static_cast<uint32_t>(groups), 1));
    MLCLUST_RETURN_IF_ERROR(Run(kWrite, m_, chunks));
    MLCLUST_RETURN_IF_ERROR(Run(kLabel, m_, m_));
    std::array<uint32_t, 4> counters{};
    MLCLUST_RETURN_IF_ERROR(buffers_[kCounters].Download(std::span<uint32_t>(counters)));
    const uint32_t k = counters[0];
    MLCLUST_RETURN_IF_ERROR(Run(kNeighbours, k, k));
    result.clusters = k;
    result.labels.resize(m_);
    MLCLUST_RETURN_IF_ERROR(buffers_[kLabels].Download(std::span<uint32_t>(result.labels)));
    result.neighbours.resize(size_t{k} * 2 * d_);
    if (k > 0) {
      MLCLUST_RETURN_IF_ERROR(
          buffers_[kNeighboursBuffer].Download(std::span<uint32_t>(result.neighbours)));
    }
    return CheckGlError(context_, kPass);
  }

 private:
  GlContext& context_;
  uint32_t m_, d_;
  uint32_t program_;
  std::vector<StorageBuffer> buffers_;
};

}  // namespace

uint64_t VoxelStartMemoryBound(uint64_t m, uint32_t d) {
  const uint64_t n = std::max<uint64_t>(m, 1);
  return n * (4 * d + 4 + 4 + 8 * d + 4) + Slots(n) * 12 + Chunks(n) * 4 + Groups(n) * 4 + 16 * d +
         8 * d + 16;
}

absl::StatusOr<VoxelStartGpuResult> VoxelGridStartGpu(GlContext& context, const PointSet& points,
                                                      uint32_t grid,
                                                      const std::atomic<bool>* cancel) {
  MLCLUST_RETURN_IF_ERROR(ValidatePoints(points));
  if (grid > (1u << 20)) {
    return absl::InvalidArgumentError(absl::StrCat("grid: ", grid, " is over 2^20"));
  }
  const uint32_t d = points.dims;
  const uint64_t m = points.num_points();
  if (d > kVoxelStartMaxDims) {
    return absl::InvalidArgumentError(absl::StrCat(
        "voxel start on the GPU: ", d, " dimensions (at most ", kVoxelStartMaxDims, ")"));
  }
  // Shader indices are 32-bit: point * d, cluster * 2d, 2 * slot.
  if (m * 2 * d >= (uint64_t{1} << 32) || Slots(m) >= (uint64_t{1} << 31)) {
    return absl::InvalidArgumentError(
        absl::StrCat("voxel start on the GPU: ", m, " points in ", d, " dimensions are too many"));
  }
  MLCLUST_RETURN_IF_ERROR(BeginPass(context, kPass));
  absl::StatusOr<VoxelStartGpuResult> made = [&]() -> absl::StatusOr<VoxelStartGpuResult> {
    const uint64_t n = std::max<uint64_t>(m, 1);
    const std::array<uint64_t, kBindings> bytes = {
        n * d * 4,     d * 16, 2 * d * 4,    n * 4, Slots(n) * 8, Chunks(n) * 4,
        Groups(n) * 4, 16,     Slots(n) * 4, n * 4, n * 4,        n * 2 * d * 4};
    MLCLUST_ASSIGN_OR_RETURN(std::vector<StorageBuffer> buffers,
                             CreateStorageBuffers(context, bytes));
    MLCLUST_RETURN_IF_ERROR(buffers[kPoints].Upload(std::span<const float>(points.values)));
    MLCLUST_ASSIGN_OR_RETURN(
        const uint32_t program,
        GetComputeProgram(context, "voxel_start",
                          absl::StrCat(kComputeShaderPrelude, kVoxelStartGlsl, kCompactScanGlsl)));
    VoxelGrid voxels(context, static_cast<uint32_t>(m), d, program, std::move(buffers));
    MLCLUST_ASSIGN_OR_RETURN(auto box, voxels.Bounds());
    const std::vector<float>& lo = box.first;
    const std::vector<float>& hi = box.second;
    MLCLUST_ASSIGN_OR_RETURN(
        std::vector<uint32_t> cells,
        VoxelStartCells(m, lo, hi, grid, cancel, [&](std::span<const uint32_t> trial) {
          return voxels.Insert(lo, hi, trial);
        }));
    MLCLUST_RETURN_IF_ERROR(CheckCancelled(cancel, "the voxel start"));
    MLCLUST_RETURN_IF_ERROR(voxels.Insert(lo, hi, cells).status());
    VoxelStartGpuResult result;
    MLCLUST_RETURN_IF_ERROR(voxels.Finish(result));
    result.cells_per_axis = std::move(cells);
    return result;
  }();
  if (!made.ok()) return PassError(kPass, made.status());
  return made;
}

}  // namespace mlclust::gpu
