#include "server/job_options.h"

#include "absl/strings/str_cat.h"
#include "core/base/status_macros.h"
#include "core/plan/device_policy.h"
#include "server/wire_registry.h"

namespace mlclust::server {

absl::StatusOr<MeshEnergyKind> MeshEnergyFromWire(v1::Energy energy) {
  MLCLUST_ASSIGN_OR_RETURN(const EnergyInfo* info, EnergyFromWire(InputKind::kMesh, energy));
  return info == nullptr ? MeshEnergyKind::kCvd : info->mesh_kind;
}

absl::StatusOr<JobPlan> PlanWireJob(const v1::JobSpec& spec) {
  const InputKind input = InputFromWire(spec.input_kind());
  JobRequest request;
  MLCLUST_ASSIGN_OR_RETURN(request.algorithm, AlgorithmFromWire(input, spec.algorithm()));
  MLCLUST_ASSIGN_OR_RETURN(request.energy, EnergyFromWire(input, spec.energy()));
  request.clusters = spec.clusters();
  request.levels_high = spec.levels_high();
  request.levels_low = spec.levels_low();
  request.seed = spec.seed();
  for (const auto& [name, value] : spec.options()) request.options.emplace_back(name, value);
  MLCLUST_ASSIGN_OR_RETURN(request.device, ParseDeviceChoice(spec.device()));
  if (spec.polygon_triangle_counts_size() > 0) {
    // Per-polygon clustering (issue 13): the CPU drivers of these algorithms only (the
    // device policy keeps their stages on the CPU: core/plan/device_policy.h).
    const std::string& name = request.algorithm->name;
    if (input != InputKind::kMesh) {
      return absl::InvalidArgumentError("polygon_triangle_counts: only for meshes");
    }
    if (name != "ml" && name != "hc" && name != "pml" && name != "emlo" && name != "bb") {
      return absl::InvalidArgumentError(
          absl::StrCat("polygon_triangle_counts: per-polygon clustering runs ml, hc, pml, emlo "
                       "and bb, not ",
                       name));
    }
  }
  return PlanJob(request);
}

namespace {

v1::OptionDescription DescribeOption(const OptionInfo& option) {
  v1::OptionDescription out;
  out.set_name(option.name);
  out.set_type(OptionTypeName(option.type));
  for (const std::string& choice : option.choices) out.add_choices(choice);
  out.set_low(option.low);
  out.set_high(option.high);
  out.set_default_value(option.default_text);
  out.set_help(option.help);
  return out;
}

std::string BuildDescription() {
  std::string build = absl::StrCat("C++ ", __cplusplus, ", ");
#if defined(__clang__)
  absl::StrAppend(&build, "clang ", __clang_major__, ".", __clang_minor__);
#elif defined(__GNUC__)
  absl::StrAppend(&build, "gcc ", __GNUC__, ".", __GNUC_MINOR__);
#endif
#ifdef NDEBUG
  absl::StrAppend(&build, ", optimised");
#else
  absl::StrAppend(&build, ", debug");
#endif
#ifdef MLCLUST_HAVE_GPU
  absl::StrAppend(&build, ", GPU backend (OpenGL compute over EGL)");
#else
  absl::StrAppend(&build, ", no GPU backend");
#endif
  return build;
}

}  // namespace

v1::ServerInfo MakeServerInfo(const ServerFacts& facts) {
  v1::ServerInfo info;
  info.set_version(kMlclustVersion);
  info.set_build(BuildDescription());
  info.set_gpu_available(facts.gpu_available);
  info.set_gl_renderer(facts.gl_renderer);
  info.set_gl_is_software(facts.gl_is_software);
  info.set_max_input_bytes(facts.max_input_bytes);
  info.set_queue_capacity(facts.queue_capacity);
  info.set_max_clusters(UINT32_MAX);
  info.set_max_point_dims(0);
  auto wire_input = [](InputKind input) {
    return input == InputKind::kMesh ? v1::INPUT_KIND_DRACO_MESH : v1::INPUT_KIND_POINTS_F32;
  };
  for (const AlgorithmInfo& algorithm : Algorithms()) {
    v1::AlgorithmDescription* out = info.add_algorithms();
    out->set_algorithm(static_cast<v1::Algorithm>(algorithm.wire));
    out->set_name(algorithm.name);
    out->set_input_kind(wire_input(algorithm.input));
    out->set_hierarchy(algorithm.hierarchy);
    out->set_title(algorithm.title);
    out->set_help(algorithm.help);
    for (const std::string& name : algorithm.energies) {
      const EnergyInfo* energy = FindEnergy(algorithm.input, name);
      if (energy != nullptr && energy->wire != 0) {
        out->add_energies(static_cast<v1::Energy>(energy->wire));
      }
    }
    for (const OptionInfo* option : AlgorithmOptions(algorithm)) {
      *out->add_options() = DescribeOption(*option);
    }
    if (algorithm.input == InputKind::kMesh) {
      v1::StageDescription* measures = out->add_stages();
      measures->set_name("measures");
      measures->set_help("face areas, centroids and normals");
      measures->set_has_gpu(StageHasGpu(algorithm, PlanStage::kMeasures));
    }
    for (const StageInfo& stage : algorithm.stages) {
      v1::StageDescription* described = out->add_stages();
      described->set_name(stage.name);
      described->set_help(stage.help);
      const std::optional<PlanStage> planned = PlanStageFromName(stage.name);
      described->set_has_gpu(planned.has_value() && StageHasGpu(algorithm, *planned));
    }
  }
  for (const EnergyInfo& energy : Energies()) {
    if (energy.wire == 0) continue;  // not on the wire yet
    v1::EnergyDescription* out = info.add_energies();
    out->set_energy(static_cast<v1::Energy>(energy.wire));
    out->set_name(energy.name);
    out->set_input_kind(wire_input(energy.input));
    out->set_help(energy.help);
  }
  return info;
}

}  // namespace mlclust::server
