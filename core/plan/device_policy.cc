#include "core/plan/device_policy.h"

#include <algorithm>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"

namespace mlclust {
namespace {

// A stage's GPU implementation: whether one exists for the algorithm, whether it covers the
// plan ("" where it does, else why not), and whether auto takes it.
struct GpuStage {
  bool exists = false;
  std::string unsupported;   // why the GPU does not cover the plan ("" where it does)
  bool auto_default = true;  // auto takes it on a hardware renderer
};

bool IsCvd(MeshEnergyKind kind) {
  return kind == MeshEnergyKind::kCvd || kind == MeshEnergyKind::kCvdAdaptive;
}

// The policy's table: for each algorithm and stage, its GPU implementation as the plan sees
// it. A new GPU stage is one entry here (and its DeviceStages method).
GpuStage GpuStageFor(const JobPlan& plan, PlanStage stage) {
  const AlgorithmInfo& algorithm = *plan.algorithm;
  const absl::string_view name = algorithm.name;
  if (algorithm.input == InputKind::kMesh) {
    switch (stage) {
      case PlanStage::kMeasures:
        return {true, "", true};  // gpu/kernels/face_measures_gpu.h
      case PlanStage::kSeed:
        // Growth rounds (section 5.2, gpu/stages/seed_growth_gpu.h): EMLO's, BB's and BB's
        // preset patches' (its energy-free growth is the same partition). VSA has no growth
        // option.
        if (name != "emlo" && name != "bb") return {};
        return {true,
                plan.seeds.growth == SeedOptions::Growth::kRounds
                    ? ""
                    : "the GPU grows seeds in rounds only (option growth rounds)",
                true};
      case PlanStage::kCluster:
        if (name == "hc") {
          // One collapse per step is latency-bound on a GPU: auto keeps the CPU's heap.
          return {true, HcGpuUnsupported(plan.multilevel, plan.mesh_energy.kind), false};
        }
        if (name == "ml") {
          // As HC's; and on llvmpipe ML with BB is far slower than the CPU's.
          return {true, MlGpuUnsupported(plan.multilevel, plan.mesh_energy.kind), false};
        }
        if (name == "pml") {
          return {true, PmlGpuUnsupported(plan.multilevel, plan.mesh_energy.kind), true};
        }
        if (name == "bb") {
          if (plan.bb_patches) return {true, "preset patches sweeps on the CPU", true};
          return {true,
                  HasGpuBoundaryDecide(plan.mesh_energy.kind)
                      ? ""
                      : absl::StrCat("the energy ", MeshEnergyName(plan.mesh_energy.kind),
                                     " has no GPU decide stage (cvd, cvd-adaptive, mwcvd-*, "
                                     "planar have)"),
                  true};
        }
        return {};  // EMLO, VSA
    }
    return {};
  }
  if (stage != PlanStage::kCluster) return {};
  const PointMultilevelOptions& levels = plan.point_multilevel;
  if (name == "hc" || name == "ml") {
    // HC's and ML's steps (RunPointHierarchyGpu): latency-bound, --device gpu only.
    return {
        true,
        levels.parallel ? "PML's levels are the parallel ones" : PointsStartGpuUnsupported(levels),
        false};
  }
  if (name == "pml") {
    // LN k-means inside the levels and the switch to ML are each a round trip per round:
    // auto keeps them on the CPU.
    const bool merges_only =
        levels.optimizer == PointMultilevelOptions::Optimizer::kNone && levels.pml_until == 0;
    return {true, PointsPmlGpuUnsupported(levels), merges_only};
  }
  if (name == "lnkmeans") {
    // Assign and the initial neighbours (gpu/kernels/ln_kmeans.h), from seeds.
    return {true,
            plan.point_init == JobPlan::PointInit::kGrid
                ? "init grid's LN k-means runs on the CPU (the GPU's starts from seeds)"
                : "",
            true};
  }
  if (name == "kmeans") return {true, "", true};  // gpu/kernels/kmeans_assign.h
  return {};                                      // X-means, bisecting k-means
}

// The stages of the plan, in order: "measures" first for meshes, then the algorithm's.
std::vector<PlanStage> StagesOf(const AlgorithmInfo& algorithm) {
  std::vector<PlanStage> stages;
  if (algorithm.input == InputKind::kMesh) stages.push_back(PlanStage::kMeasures);
  for (const StageInfo& info : algorithm.stages) {
    const std::optional<PlanStage> stage = PlanStageFromName(info.name);
    if (stage.has_value()) stages.push_back(*stage);
  }
  return stages;
}

// The device limits for one GPU stage: "" where the stage fits, else the limit it breaks.
std::string OverLimit(const DeviceCaps& caps, const InputShape& input, const JobPlan& plan,
                      PlanStage stage) {
  if (plan.algorithm->input == InputKind::kPoints && stage == PlanStage::kCluster &&
      input.dims > kGpuPointMaxDims &&
      (plan.algorithm->name == "hc" || plan.algorithm->name == "ml" ||
       plan.algorithm->name == "pml")) {
    return absl::StrCat(input.dims, " dimensions: over the GPU's ", kGpuPointMaxDims);
  }
  if (caps.free_bytes.has_value() && caps.gpu_working_set && input.elements > 0) {
    const uint64_t needed = caps.gpu_working_set(stage, plan, input);
    if (needed > *caps.free_bytes) {
      return absl::StrCat("its GPU working set of ", needed >> 20, " MiB (", needed,
                          " bytes) is over the device's free ", *caps.free_bytes >> 20, " MiB (",
                          *caps.free_bytes, " bytes)");
    }
  }
  return "";
}

}  // namespace

std::string HcGpuUnsupported(const MultilevelOptions& options, MeshEnergyKind energy) {
  if (options.parallel) return "PML's levels are gpu/stages/multilevel_gpu.h's";
  if (!IsCvd(energy)) return "the GPU has the merge cost of cvd and cvd-adaptive only";
  if (options.optimizer != MultilevelOptions::Optimizer::kNone) {
    return "the GPU's levels are merges only (HC: optimizer none)";
  }
  if (options.p_percent != 0) return "p-percent is not on the GPU";
  return "";
}

std::string PmlGpuUnsupported(const MultilevelOptions& options, MeshEnergyKind energy) {
  if (!options.parallel) return "only PML (parallel levels) runs on the GPU";
  if (!IsCvd(energy)) return "the GPU has the merge cost of cvd and cvd-adaptive only";
  if (options.optimizer == MultilevelOptions::Optimizer::kEmlo) {
    return "the GPU's PML optimises with BB (optimizer bb) or not at all (none), not EMLO";
  }
  if (options.optimizer == MultilevelOptions::Optimizer::kBoundaryBased &&
      options.connectivity_guard &&
      options.guard == ConnectivityGuardKind::kVertexBoundaryEdgeCount) {
    return "the GPU's PML with BB checks moves with the ring test or not at all, not "
           "vertex-count";
  }
  if (options.p_percent != 0) return "p-percent is not on the GPU";
  if (options.pml_until != 0) return "pml-until (the switch to ML) is not on the GPU";
  return "";
}

std::string MlGpuUnsupported(const MultilevelOptions& options, MeshEnergyKind energy) {
  if (options.optimizer == MultilevelOptions::Optimizer::kNone) {
    return HcGpuUnsupported(options, energy);
  }
  if (options.parallel) return "PML's levels are RunParallelMultilevelGpu's";
  if (options.optimizer != MultilevelOptions::Optimizer::kBoundaryBased) {
    return "the GPU's ML optimises with BB (optimizer bb) or not at all (none, HC's steps), "
           "not EMLO";
  }
  // The rest as PML with BB: the energies, the guard, no p-percent.
  MultilevelOptions as_pml = options;
  as_pml.parallel = true;
  return PmlGpuUnsupported(as_pml, energy);
}

std::string PointsStartGpuUnsupported(const PointMultilevelOptions& options) {
  if (options.start == PointMultilevelOptions::Start::kOptimisedGrid) {
    return "start optimised-grid (LN k-means on the voxel clusters before level 0, "
           "Fig. 6.5 / 6.8) runs on the CPU only";
  }
  return "";
}

std::string PointsPmlGpuUnsupported(const PointMultilevelOptions& options) {
  if (!options.parallel) return "one merge per level is RunPointHierarchyGpu's";
  return PointsStartGpuUnsupported(options);
}

bool HasGpuBoundaryDecide(MeshEnergyKind energy) {
  switch (energy) {
    case MeshEnergyKind::kCvd:
    case MeshEnergyKind::kCvdAdaptive:
    case MeshEnergyKind::kMwcvdArea:
    case MeshEnergyKind::kMwcvdVariance:
    case MeshEnergyKind::kMwcvdMax:
    case MeshEnergyKind::kPlanar:
      return true;
    default:
      return false;
  }
}

bool StageHasGpu(const AlgorithmInfo& algorithm, PlanStage stage) {
  JobPlan plan;  // the defaults: whether an implementation exists does not depend on options
  plan.algorithm = &algorithm;
  return GpuStageFor(plan, stage).exists;
}

absl::Status PlanDevices(const DeviceCaps& caps, JobPlan& plan) {
  return PlanDevices(caps, InputShape(), plan);
}

absl::Status PlanDevices(const DeviceCaps& caps, const InputShape& input, JobPlan& plan) {
  const AlgorithmInfo& algorithm = *plan.algorithm;
  const std::vector<PlanStage> stages = StagesOf(algorithm);
  const bool any_gpu = std::any_of(stages.begin(), stages.end(), [&](PlanStage stage) {
    return GpuStageFor(plan, stage).exists;
  });
  if (plan.device == DeviceChoice::kGpu) {
    if (!caps.gpu) {
      return absl::FailedPreconditionError("option device: 'gpu' but this server has no GPU");
    }
    if (!any_gpu) {
      return absl::FailedPreconditionError(
          absl::StrCat("option device: 'gpu' but no stage of ", algorithm.name, " on ",
                       InputKindName(algorithm.input), " has a GPU implementation yet"));
    }
    if (input.polygons) {
      return absl::FailedPreconditionError(
          "option device: 'gpu' but per-polygon clustering (polygon_triangle_counts) runs on "
          "the CPU");
    }
  }
  plan.stages.clear();
  for (PlanStage stage : stages) {
    StagePlan planned{stage, StageDevice::kCpu, ""};
    const GpuStage gpu = GpuStageFor(plan, stage);
    std::string why;  // why the stage stays on the CPU
    if (plan.device == DeviceChoice::kCpu) {
      // Asked for.
    } else if (!gpu.exists) {
      why = absl::StrCat(algorithm.name, "'s ", PlanStageName(stage),
                         " stage has no GPU implementation");
    } else if (!gpu.unsupported.empty()) {
      why = gpu.unsupported;
    } else if (input.polygons) {
      why = "per-polygon clustering runs on the CPU";
    } else if (!caps.gpu) {
      why = "this server has no GPU";
    } else if (plan.device == DeviceChoice::kAuto && caps.gpu_is_software) {
      // A software renderer (llvmpipe) is slower than the CPU for these kernels.
      why = "auto uses the GPU only where it is hardware";
    } else if (plan.device == DeviceChoice::kAuto && !gpu.auto_default) {
      // One merge per level (HC's and ML's steps), and LN k-means' rounds inside PML's point
      // levels, are latency-bound on a GPU: auto keeps them on the CPU.
      why = "auto keeps this stage on the CPU";
    } else {
      planned.device = StageDevice::kGpu;
    }
    // Said where the job asked for the GPU; auto's ordinary choices go unremarked (its
    // limits are said: FitDevicesToInput).
    if (plan.device == DeviceChoice::kGpu) planned.why = std::move(why);
    plan.stages.push_back(std::move(planned));
  }
  return FitDevicesToInput(caps, input, plan);
}

absl::Status FitDevicesToInput(const DeviceCaps& caps, const InputShape& input, JobPlan& plan) {
  for (StagePlan& stage : plan.stages) {
    if (stage.device != StageDevice::kGpu) continue;
    const std::string over = OverLimit(caps, input, plan, stage.stage);
    if (over.empty()) continue;
    if (plan.device == DeviceChoice::kGpu) {
      return absl::FailedPreconditionError(
          absl::StrCat("option device: 'gpu' but the ", stage.name(), " stage cannot run on ",
                       caps.renderer, ": ", over, " (device auto runs it on the CPU)"));
    }
    stage.device = StageDevice::kCpu;
    stage.why = absl::StrCat(over, ": on the CPU");
  }
  return absl::OkStatus();
}

bool UsesGpu(const JobPlan& plan) {
  return std::any_of(plan.stages.begin(), plan.stages.end(),
                     [](const StagePlan& stage) { return stage.device == StageDevice::kGpu; });
}

WorkerLane LaneFor(const JobPlan& plan, bool has_cpu_workers, bool draws_preview) {
  if (!has_cpu_workers) return WorkerLane::kGl;
  return UsesGpu(plan) || draws_preview ? WorkerLane::kGl : WorkerLane::kCpu;
}

bool MayUseGpu(DeviceChoice choice, bool may_be_hardware) {
  return choice == DeviceChoice::kGpu || (choice == DeviceChoice::kAuto && may_be_hardware);
}

std::string StageDeviceName(const StagePlan& stage, const DeviceCaps& caps) {
  return stage.device == StageDevice::kGpu ? caps.renderer : "cpu";
}

}  // namespace mlclust
