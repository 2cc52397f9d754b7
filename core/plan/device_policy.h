// The device policy: the one place that decides where a job runs. For every stage of a
// job's plan it decides CPU or GPU, for the job the worker lane, and whether the job fits
// the device. Nothing else decides: the registry's run functions
// (core/cluster/registry.cc), the server's runner (server/job_runner.cc) and the GPU
// stages (gpu/stages/) follow plan.stages; a device error mid-job is the job's error (no
// fallback to the CPU once a stage has started). The GPU stages check their options with
// the coverage functions below (the same functions the plan reads), so the rules are
// written once.
//
// The rules, stage by stage (PlanDevices):
//  - kCpu: every stage on the CPU.
//  - A stage runs on the GPU where its algorithm has a GPU implementation of it, that
//    implementation covers the plan (energy, options: the *Unsupported functions say why
//    not) and the input (InputShape::polygons: never), and the device choice takes it:
//    kGpu on any renderer; kAuto only on a hardware renderer and only for the stages
//    whose GPU implementation is auto's default (one collapse per step, as HC's and ML's
//    steps, is latency-bound on a GPU: those run there with kGpu only).
//  - Device limits (the working set against the device's free memory, the point levels'
//    kGpuPointMaxDims): kGpu refuses the job (FAILED_PRECONDITION naming the limit); kAuto
//    plans the stage on the CPU and says why in StagePlan::why.
//  - kGpu refuses a job no stage of whose algorithm has a GPU implementation, a
//    per-polygon job, and a job on a machine without a GPU. A job some of whose stages the
//    GPU does not cover is not refused: those stages run on the CPU, and StagePlan::why
//    says why (the runner sends it in a Progress of stage "plan" before any stage).
//  - A new GPU stage: its kernel, its stage (a DeviceStages method), and one entry in this
//    policy's table (device_policy.cc GpuStageFor), with its working set in
//    gpu/stages/gpu_working_set.cc.
//
// Free memory: DeviceCaps::free_bytes, where the driver reports it (GL_NVX_gpu_memory_info,
// GL_ATI_meminfo; gpu/context/gl_context.h QueryDeviceMemory). Where it reports none (Mesa's
// llvmpipe, whose buffers are host memory that the server's input budgets bound), nothing
// is checked. The working set of a stage is DeviceCaps::gpu_working_set's (the server
// passes gpu/stages/gpu_working_set.h's bound); unset, nothing is checked.
#ifndef MLCLUST_CORE_PLAN_DEVICE_POLICY_H_
#define MLCLUST_CORE_PLAN_DEVICE_POLICY_H_

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <utility>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/cluster/multilevel.h"
#include "core/cluster/point_clustering.h"
#include "core/cluster/registry.h"
#include "core/energy/energies.h"

namespace mlclust {

// What is known of a job's input when it is planned. Zeros where not known yet: a mesh's
// faces before it is decoded (the plan at submit); the runner fits the plan again once they
// are (FitDevicesToInput).
struct InputShape {
  uint64_t elements = 0;  // faces or points
  uint64_t vertices = 0;  // meshes
  uint32_t dims = 0;      // points
  bool polygons = false;  // per-polygon clustering (JobSpec.polygon_triangle_counts)
};

// What the machine running the job offers.
struct DeviceCaps {
  DeviceCaps() = default;
  DeviceCaps(bool has_gpu, bool software, std::string gl_renderer)
      : gpu(has_gpu), gpu_is_software(software), renderer(std::move(gl_renderer)) {}

  bool gpu = false;              // a GL context is available
  bool gpu_is_software = false;  // ... and it is a software renderer (llvmpipe)
  std::string renderer;          // the GL renderer string
  // The device's free memory in bytes; nullopt where the driver reports none.
  std::optional<uint64_t> free_bytes;
  // The most bytes of GPU memory `stage` allocates for `plan` on `input`; unset where not
  // known (nothing checked).
  std::function<uint64_t(PlanStage stage, const JobPlan& plan, const InputShape& input)>
      gpu_working_set;
};

// Fills plan.stages as the rules above say, for `input` as far as it is known. Each stage's
// `why` says why a stage is on the CPU where the job did not ask for the CPU.
// FAILED_PRECONDITION (naming option device) where kGpu cannot be met.
absl::Status PlanDevices(const DeviceCaps& caps, const InputShape& input, JobPlan& plan);
// PlanDevices with nothing known of the input.
absl::Status PlanDevices(const DeviceCaps& caps, JobPlan& plan);

// The device limits alone, once more of the input is known (a mesh's faces after decode):
// a GPU stage over a limit moves to the CPU (kAuto, with why) or refuses the job (kGpu,
// FAILED_PRECONDITION). Never moves a stage to the GPU, so a job stays on its lane.
absl::Status FitDevicesToInput(const DeviceCaps& caps, const InputShape& input, JobPlan& plan);

// Whether any stage of the plan runs on the GPU.
bool UsesGpu(const JobPlan& plan);

// Which worker takes the job. With CPU workers (serve --workers N), a job goes to the
// worker that owns the GL context where its plan puts a stage on the GPU or it draws a
// preview; without, that worker takes every job.
enum class WorkerLane { kGl, kCpu };
WorkerLane LaneFor(const JobPlan& plan, bool has_cpu_workers, bool draws_preview);

// Whether a job of `choice` can put any stage on a GPU, where the machine's GPU, if any,
// `may_be_hardware` (else EGL can give only a software renderer, which auto leaves alone).
// The embedded server creates no GL context where not (its creation costs ~0.1 s of CPU).
bool MayUseGpu(DeviceChoice choice, bool may_be_hardware);

// "cpu", or the renderer for a GPU stage.
std::string StageDeviceName(const StagePlan& stage, const DeviceCaps& caps);

// Whether `algorithm` has a GPU implementation of `stage` (GetServerInfo's has_gpu).
bool StageHasGpu(const AlgorithmInfo& algorithm, PlanStage stage);

// ---------------------------------------------------------------------------------------
// What each GPU implementation covers: "" where it covers the options, else why not. The
// GPU drivers of gpu/stages/ refuse (UNIMPLEMENTED) what these refuse.

// HC's steps (gpu/stages/hierarchy_gpu.h): one merge per level, merges only, for the
// energies whose merge cost the GPU has (cvd, cvd-adaptive), without p-percent.
std::string HcGpuUnsupported(const MultilevelOptions& options, MeshEnergyKind energy);
// PML's levels (gpu/stages/multilevel_gpu.h): merges only or with BB sweeps (Alg. 5.7;
// ring test or no guard), without p-percent or the switch to ML, cvd and cvd-adaptive.
std::string PmlGpuUnsupported(const MultilevelOptions& options, MeshEnergyKind energy);
// ML's levels (gpu/stages/multilevel_gpu.h): optimizer none (HC's steps) or bb (Alg. 5.6,
// one merge then BB sweeps per level), otherwise as PML's.
std::string MlGpuUnsupported(const MultilevelOptions& options, MeshEnergyKind energy);
// The point levels (gpu/stages/points_multilevel_gpu.h): PML's (parallel) levels, merges
// only or with LN k-means, pml-until included; HC's and ML's steps are
// RunPointHierarchyGpu's (options.parallel false).
std::string PointsPmlGpuUnsupported(const PointMultilevelOptions& options);
// The point hierarchies' start on the GPU: the voxel clusters only (start grid); the text's
// optimised-grid start is the CPU's.
std::string PointsStartGpuUnsupported(const PointMultilevelOptions& options);

// The energies whose BB decide stage has a GPU cost (gpu/kernels/bb_decide.h): the
// proxy-point energies (cvd, cvd-adaptive, mwcvd-*) and planar.
bool HasGpuBoundaryDecide(MeshEnergyKind energy);

// The most dimensions the GPU's point levels take (gpu/kernels/voxel_start.h's
// kVoxelStartMaxDims asserts the same).
inline constexpr uint32_t kGpuPointMaxDims = 64;

}  // namespace mlclust

#endif  // MLCLUST_CORE_PLAN_DEVICE_POLICY_H_
