// Turns a JobSpec from the wire into a job plan through the registry
// (core/cluster/registry.h), checking every field: a bad value is INVALID_ARGUMENT naming
// the field or option; an algorithm this server does not run for the input is
// UNIMPLEMENTED. The options each algorithm accepts, with their types, ranges, defaults and
// help, are the registry's (`mlclust help`, `mlclust info`, GetServerInfo list them).
#ifndef MLCLUST_SERVER_JOB_OPTIONS_H_
#define MLCLUST_SERVER_JOB_OPTIONS_H_

#include <cstdint>
#include <string>

#include "absl/status/statusor.h"
#include "core/cluster/registry.h"
#include "core/energy/energies.h"
#include "mlclust/v1/mlclust.pb.h"

namespace mlclust::server {

// The plan of `spec` (input kind, algorithm, energy, clusters, levels, seed, options and
// device). Devices are not planned yet (server/job_runner.h PlanJobOnDevice plans them).
// A job that names no algorithm runs ML, for meshes as for points.
absl::StatusOr<JobPlan> PlanWireJob(const v1::JobSpec& spec);

// What GetServerInfo reports beyond the registry.
struct ServerFacts {
  bool gpu_available = false;
  std::string gl_renderer;
  bool gl_is_software = false;
  uint64_t max_input_bytes = 0;
  uint32_t queue_capacity = 0;
};

// The GetServerInfo answer: version, build, device, limits, and every algorithm and energy
// of the registry with their options and stages.
v1::ServerInfo MakeServerInfo(const ServerFacts& facts);

// mlclust's version (CMakeLists.txt's project VERSION; tests/e2e/cli_test.sh checks that
// they agree).
inline constexpr char kMlclustVersion[] = "0.1.0";

// The core energy kind of a wire energy (ENERGY_UNSPECIFIED is CVD).
absl::StatusOr<MeshEnergyKind> MeshEnergyFromWire(v1::Energy energy);

}  // namespace mlclust::server

#endif  // MLCLUST_SERVER_JOB_OPTIONS_H_
