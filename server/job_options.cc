#include "server/job_options.h"

#include "absl/strings/str_cat.h"
#include "core/base/status_macros.h"
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
  return PlanJob(request);
}

absl::StatusOr<MeshEnergyOptions> PlanMeshEnergy(const v1::JobSpec& spec) {
  MeshEnergyOptions energy;
  MLCLUST_ASSIGN_OR_RETURN(energy.kind, MeshEnergyFromWire(spec.energy()));
  JobPlan plan;
  plan.mesh_energy = energy;
  for (const auto& [name, text] : spec.options()) {
    const OptionInfo* option = nullptr;
    for (const OptionInfo& candidate : EnergyOptions()) {
      if (candidate.name == name) option = &candidate;
    }
    if (option == nullptr) {
      return absl::InvalidArgumentError(absl::StrCat("option ", name, " is not an energy option"));
    }
    MLCLUST_ASSIGN_OR_RETURN(OptionValue value, ParseOptionValue(*option, text));
    option->apply(value, plan);
  }
  MLCLUST_RETURN_IF_ERROR(ValidateMeshEnergyOptions(plan.mesh_energy));
  return plan.mesh_energy;
}

}  // namespace mlclust::server
