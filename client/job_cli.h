// What `mlclust mesh` and `mlclust points` share: the job's flags (server, algorithm,
// energy, options, levels), running it on --server or an embedded server, and the outputs
// every job writes (--levels-csv, --plot, --labels, the JSON summary).
#ifndef MLCLUST_CLIENT_JOB_CLI_H_
#define MLCLUST_CLIENT_JOB_CLI_H_

#include <cstdint>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "client/cli.h"
#include "client/client.h"
#include "core/cluster/registry.h"
#include "core/energy/energies.h"
#include "core/hierarchy/hierarchy.h"
#include "mlclust/v1/mlclust.pb.h"
#include "server/server.h"

namespace mlclust::cli {

// --server ADDR: HOST:PORT (a name, IPv4 or [IPv6]) with a port in 1..65535, a gRPC URI
// (unix:PATH, dns:///HOST:PORT, ...) passed as it is, or several replicas.
absl::Status CheckServerAddress(const std::string& address);

// A failed call to the server at `address`, in plain words where gRPC's text is about
// the connection (the original text follows for the record).
absl::Status PlainConnectionError(const absl::Status& status, const std::string& address);

absl::StatusOr<std::string> ReadFileBytes(const std::string& path);
// --levels-csv: a row "clusters,energy" per level.
absl::Status WriteLevelsCsv(const std::string& path, const HierarchyLog& log);
// --labels: one line per element.
absl::Status WriteLabels(const std::string& path, std::span<const uint32_t> labels);

// The command line of mesh and points: --server, --algo (`input`'s algorithms), the
// command's `own` rows, --levels, --seed, --device, --detach, --quiet, --json; then the
// registry's options of `input`, and the connection flags.
std::vector<FlagGroup> JobFlagGroups(InputKind input, const std::vector<Flag>& own);

// Done.devices as a JSON object, each stage's device as it ran ({"measures": "llvmpipe ...",
// "cluster": "cpu"}); {} from a server that predates it.
std::string DevicesJson(const v1::Done& done);
// Where the job ran, for a summary line: "on DEVICE" where every stage ran on one ("cpu", a
// renderer; Done.device from a server that predates Done.devices), else each stage's
// ("with cluster on cpu, measures on llvmpipe ...", the CPU's stages first).
std::string DevicesSummary(const v1::Done& done);

// Whether this machine has a device node a hardware GL driver opens: a DRM render node
// (/dev/dri/renderD*) or NVIDIA's (/dev/nvidiactl).
bool HardwareGpuDevicePresent();

// The options of the server started inside this process where no --server is given: no
// logs, no levels kept for watch (nothing outlives the command), and no GL context where
// the job cannot use one (--device cpu, or auto without a GPU device; not with --preview).
server::ServerOptions EmbeddedServerOptions(const Arguments& args);

// --detach: the job is submitted and its id printed; watch it with `mlclust watch`.
int Detach(const Arguments& args, const v1::JobSpec& spec, const std::string& payload);

// Runs `spec` on the server --server names, or on one started inside this process, with a
// progress line on a terminal. `labels_for_clusters`: the K of --clusters, whose level's
// labels the client rebuilds while the stream arrives (RunOptions::labels_for_clusters).
absl::StatusOr<client::JobResult> RunOnServer(const Arguments& args, const v1::JobSpec& spec,
                                              const std::string& payload, double* seconds,
                                              v1::Accepted* accepted = nullptr,
                                              uint32_t labels_for_clusters = 0);

// After a job: the server sent one label per element (`elements`, named `element_name`,
// "faces" or "points"), and --levels-csv and --plot (titled `plot_title`) are written.
absl::Status WriteLevelOutputs(const Arguments& args, const client::JobResult& result,
                               size_t elements, const std::string& element_name,
                               const std::string& plot_title);

// The level --clusters K writes: the last level with exactly K clusters (a single-level
// algorithm's result follows its start at the same K), else the first with fewer.
absl::StatusOr<size_t> ChooseLevel(const HierarchyLog& log, uint32_t k);

// The labels at `level`: those the client rebuilt as the stream arrived where it chose the
// same level, else replayed from level 0. The same labels either way.
absl::StatusOr<std::vector<ClusterId>> LabelsOfLevel(client::JobResult& result, size_t level);

// "; elbows at 6, 12" (empty without elbows).
std::string ElbowNote(const v1::Done& done);

// The job summary as one JSON object (--json): what ran, where, what came back, and the
// level written.
std::string SummaryJson(const Arguments& args, const std::string& input,
                        const std::string& element_name, size_t elements,
                        const AlgorithmInfo& algorithm, const v1::JobSpec& spec,
                        const HierarchyLog& log, double seconds, const v1::Done& done,
                        std::optional<size_t> level, const std::string& auto_k,
                        const std::set<std::string>& not_written = {});

// --levels K_HI:K_LO into `spec` (hierarchies only).
absl::Status SetLevels(const Arguments& args, bool hierarchy, v1::JobSpec& spec);
// --energy into `spec` (through the registry; not given: the algorithm's default).
absl::Status SetEnergy(const Arguments& args, InputKind input, v1::JobSpec& spec);
// --algo (through the registry; not given: the default).
absl::StatusOr<const AlgorithmInfo*> GetAlgorithm(const Arguments& args, InputKind input);
// Every registry option given travels as text: the server checks it against the algorithm.
void SetOptions(const Arguments& args, InputKind input, v1::JobSpec& spec);
// --energy (every mesh energy, also those not on the wire; `default_name` where not given)
// and the energy options, checked.
absl::StatusOr<MeshEnergyOptions> EnergyFromArguments(const Arguments& args,
                                                      const std::string& default_name);

}  // namespace mlclust::cli

#endif  // MLCLUST_CLIENT_JOB_CLI_H_
