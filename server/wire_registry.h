// The registry (core/cluster/registry.h) seen from the wire: mlclust.v1 enums to registry
// entries and back. The registry keeps the wire values as numbers (core has no proto); the
// static_asserts and tests/server/wire_registry_test.cc hold the two together.
#ifndef MLCLUST_SERVER_WIRE_REGISTRY_H_
#define MLCLUST_SERVER_WIRE_REGISTRY_H_

#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "core/cluster/registry.h"
#include "mlclust/v1/mlclust.pb.h"

namespace mlclust::server {

static_assert(v1::ALGORITHM_HC == 1 && v1::ALGORITHM_ML == 2 && v1::ALGORITHM_PML == 3 &&
              v1::ALGORITHM_EMLO == 4 && v1::ALGORITHM_BB == 5 && v1::ALGORITHM_VSA == 6 &&
              v1::ALGORITHM_LN_KMEANS == 7 && v1::ALGORITHM_KMEANS == 8 &&
              v1::ALGORITHM_XMEANS == 9 && v1::ALGORITHM_BISECTING == 10);

// The enum value's name, or its number where this build does not know it ("algorithm 99").
inline std::string WireAlgorithmName(int value) {
  const std::string& name = v1::Algorithm_Name(static_cast<v1::Algorithm>(value));
  return name.empty() ? absl::StrCat(value) : name;
}
inline std::string WireEnergyName(int value) {
  const std::string& name = v1::Energy_Name(static_cast<v1::Energy>(value));
  return name.empty() ? absl::StrCat(value) : name;
}

inline InputKind InputFromWire(v1::InputKind kind) {
  return kind == v1::INPUT_KIND_POINTS_F32 ? InputKind::kPoints : InputKind::kMesh;
}

// ALGORITHM_UNSPECIFIED: the input's default (ML). A value this build does not know:
// INVALID_ARGUMENT naming it by number. One the registry has only for the other input:
// UNIMPLEMENTED with the wire names of those it has.
inline absl::StatusOr<const AlgorithmInfo*> AlgorithmFromWire(InputKind input, int value) {
  if (value == v1::ALGORITHM_UNSPECIFIED) return &DefaultAlgorithm(input);
  if (const AlgorithmInfo* found = FindAlgorithmByWire(input, value)) return found;
  std::vector<std::string> available;
  for (const AlgorithmInfo& algorithm : Algorithms()) {
    if (algorithm.input == input) available.push_back(WireAlgorithmName(algorithm.wire));
  }
  const std::string message =
      absl::StrCat("algorithm ", WireAlgorithmName(value), " is not available for ",
                   input == InputKind::kMesh ? "meshes" : "points",
                   " on this server (available: ", absl::StrJoin(available, ", "), ")");
  if (!v1::Algorithm_IsValid(value)) return absl::InvalidArgumentError(message);
  return absl::UnimplementedError(message);
}

// ENERGY_UNSPECIFIED: nullptr (the algorithm's default energy). Otherwise the input's
// energy of that wire value, or INVALID_ARGUMENT naming the value and what is available.
inline absl::StatusOr<const EnergyInfo*> EnergyFromWire(InputKind input, int value) {
  if (value == v1::ENERGY_UNSPECIFIED) return nullptr;
  if (const EnergyInfo* found = FindEnergyByWire(input, value)) return found;
  std::vector<std::string> available;
  for (const EnergyInfo& energy : Energies()) {
    if (energy.input == input && energy.wire != 0) {
      available.push_back(WireEnergyName(energy.wire));
    }
  }
  return absl::InvalidArgumentError(
      absl::StrCat("energy: ", WireEnergyName(value), " is not ",
                   input == InputKind::kMesh ? "a mesh" : "a point",
                   " energy (available: ", absl::StrJoin(available, ", "), ")"));
}

}  // namespace mlclust::server

#endif  // MLCLUST_SERVER_WIRE_REGISTRY_H_
