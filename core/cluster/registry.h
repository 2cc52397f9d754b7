// The registry of energies and algorithms: the one list every other part reads.
//
// An entry says what a user can ask for by name (the CLI's --algo / --energy), by wire enum
// (mlclust.v1.Algorithm / Energy, kept here as numbers so that core needs no proto), what
// input it takes (a mesh or points), its options (type, range, default and help text), the
// stages it runs (which of them run on the GPU is the device policy's,
// core/plan/device_policy.h), and how it plans and runs a job. The server's option parsing
// (server/job_options.cc), the wire mapping (server/wire_registry.h), the CLI's option table and
// usage text, GetServerInfo, every "available: ..." message and the parameterised tests all read
// it; nothing else lists the algorithms or energies. CONTRIBUTING.md says how to add one.
//
// Help texts that carry the dissertation's name cite the equation or algorithm they
// implement; our extensions say "ours".
#ifndef MLCLUST_CORE_CLUSTER_REGISTRY_H_
#define MLCLUST_CORE_CLUSTER_REGISTRY_H_

#include <atomic>
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/cluster/bisecting_kmeans.h"
#include "core/cluster/kmeans.h"
#include "core/cluster/mesh_clustering.h"
#include "core/cluster/multilevel.h"
#include "core/cluster/patches.h"
#include "core/cluster/point_clustering.h"
#include "core/cluster/vsa.h"
#include "core/cluster/xmeans.h"
#include "core/energy/energies.h"
#include "core/hierarchy/hierarchy.h"
#include "core/points/points.h"

namespace mlclust {

class DeviceStages;  // core/cluster/device_stages.h
struct JobPlan;

enum class InputKind { kMesh, kPoints };
const char* InputKindName(InputKind input);  // "mesh", "points"

// ---------------------------------------------------------------------------------------
// Devices. A job asks for one; its plan says, stage by stage, which implementation runs.

enum class DeviceChoice {
  kAuto,  // the GPU for stages that have a GPU implementation, where the GPU is hardware
  kGpu,   // the GPU for stages that have one, even a software renderer; needs a GPU
  kCpu,   // every stage on the CPU
};
// "" and "auto", "gpu", "cpu". INVALID_ARGUMENT naming 'device' otherwise.
absl::StatusOr<DeviceChoice> ParseDeviceChoice(absl::string_view name);

enum class StageDevice { kCpu, kGpu };

// The stages a plan names, indexed by enum (Progress.stage is PlanStageName's).
enum class PlanStage {
  kMeasures,  // meshes: face areas, centroids and normals
  kSeed,      // k initial clusters
  kCluster,   // the algorithm's main stage
};
const char* PlanStageName(PlanStage stage);  // "measures", "seed", "cluster"
std::optional<PlanStage> PlanStageFromName(absl::string_view name);

// One stage of an algorithm, as the registry lists it. Whether it has a GPU implementation,
// and for which plans, is the device policy's (core/plan/device_policy.h).
struct StageInfo {
  std::string name;  // "measures", "seed", "cluster": Progress.stage
  std::string help;
};

// One stage of a job's plan: where it runs (core/plan/device_policy.h PlanDevices decides).
struct StagePlan {
  PlanStage stage = PlanStage::kCluster;
  StageDevice device = StageDevice::kCpu;
  // Why the stage is on the CPU where the job did not ask for the CPU ("" otherwise).
  std::string why;
  const char* name() const { return PlanStageName(stage); }
};

// ---------------------------------------------------------------------------------------
// Options.

struct JobPlan;

struct OptionValue {
  std::string text;     // as given (a kChoice's choice)
  double number = 0;    // kNumber
  int64_t integer = 0;  // kInteger
};

struct OptionInfo {
  enum class Type { kChoice, kInteger, kNumber };
  std::string name;  // as on the wire (JobSpec.options) and on the CLI (--name)
  Type type = Type::kChoice;
  std::vector<std::string> choices;  // kChoice
  double low = 0, high = 0;          // kInteger, kNumber: the closed range accepted
  std::string default_text;          // what not giving the option means
  std::string help;
  // Whose the default is: the dissertation's variant, ours, or not marked (the text does not
  // decide it). `mlclust help` says which (OptionDefaultNote).
  enum class Origin { kUnmarked, kText, kOurs };
  Origin default_origin = Origin::kUnmarked;
  // Where the default is ours: the text's variant, as the option's text, which the option
  // "preset dissertation" sets unless the option is given; "" where the text leaves the value
  // to the user (the voxel grid's a, section 6.2): the preset then needs the option given.
  std::string text_variant;
  // Writes the parsed value into the plan.
  std::function<void(const OptionValue&, JobPlan&)> apply;
};

// "choice", "integer", "number".
const char* OptionTypeName(OptionInfo::Type type);

// The default as `mlclust help` prints it: "flood (ours; the text's: free, preset
// dissertation)", "lneigh (the text's)", or the plain default where unmarked.
std::string OptionDefaultNote(const OptionInfo& option);

// The value of the option "preset" that runs the text's variants (default_origin kOurs
// options set to their text_variant unless given explicitly).
inline constexpr char kDissertationPreset[] = "dissertation";

// Parses `text` as `option` says. INVALID_ARGUMENT "option NAME: 'TEXT' is not ...".
absl::StatusOr<OptionValue> ParseOptionValue(const OptionInfo& option, absl::string_view text);

// ---------------------------------------------------------------------------------------
// Energies.

struct EnergyInfo {
  std::string name;  // "cvd", "planar", ...
  int wire = 0;      // mlclust.v1.Energy; 0 where the energy is not on the wire yet
  InputKind input = InputKind::kMesh;
  MeshEnergyKind mesh_kind = MeshEnergyKind::kCvd;  // meshes only
  std::string help;
};

// Every energy, in the order of the wire enum (those without a wire value last).
std::span<const EnergyInfo> Energies();
// The options every mesh energy reads (density mapping, MWCVD's p, the sphere's Delta_zero);
// each names in its help the energies that use it.
std::span<const OptionInfo> EnergyOptions();

const EnergyInfo* FindEnergy(InputKind input, absl::string_view name);
const EnergyInfo* FindEnergyByWire(InputKind input, int wire);
const EnergyInfo* FindEnergyByKind(MeshEnergyKind kind);

// ---------------------------------------------------------------------------------------
// Algorithms.

// Reports a stage starting (or a message within it): the server turns it into a Progress
// event naming the stage's device.
struct RunContext {
  std::function<void(const StagePlan& stage, const std::string& message)> on_stage;
  // How far a stage is, 0..1, where the run function knows it (Progress.fraction: VSA's
  // iterations of a fixed count); may be empty. Hierarchies' fractions come from the levels.
  std::function<void(const StagePlan& stage, double fraction, const std::string& message)>
      on_fraction;
  const std::atomic<bool>* cancel = nullptr;
  // The stages on the GPU (core/cluster/device_stages.h), where the runner has one; a run
  // function whose plan puts a stage on the GPU fails with FAILED_PRECONDITION without it.
  DeviceStages* devices = nullptr;
};

struct RunSummary {
  uint32_t start_clusters = 0;  // level 0's cluster count
  uint32_t final_clusters = 0;  // the last level's
};

using MeshRunFunction = absl::StatusOr<RunSummary> (*)(const MeshProblem& problem,
                                                       const JobPlan& plan, LevelSink& sink,
                                                       const RunContext& context);
using PointRunFunction = absl::StatusOr<RunSummary> (*)(const PointSet& points, const JobPlan& plan,
                                                        LevelSink& sink, const RunContext& context);

struct AlgorithmInfo {
  std::string name;  // the CLI's --algo: "hc", "ml", "emlo", ...
  int wire = 0;      // mlclust.v1.Algorithm
  InputKind input = InputKind::kMesh;
  // Every level from many clusters to few (clusters = the lowest level to compute, 0 = one);
  // otherwise one K, and the result comes as two levels: the seeding at K, then the result.
  bool hierarchy = false;
  // Single-level algorithms that can start without a K (LN k-means' init grid) say so in
  // their plan; all others need clusters >= 1.
  // A divisive hierarchy (bisecting k-means): clusters (>= 1, required) is its top, K; its
  // levels go from K clusters down to one.
  bool divisive = false;
  // A single-level algorithm that chooses its own number of clusters (X-means): clusters is
  // the smallest it starts from (k_min); the result, the last level, may have more.
  bool chooses_k = false;
  std::string title;  // "multilevel clustering (Alg. 4.1)"
  std::string help;
  std::vector<std::string> energies;      // the energies it runs, by name; the first is the default
  std::vector<OptionInfo> options;        // its own; mesh algorithms also read EnergyOptions()
  std::vector<StageInfo> stages;          // in order
  MeshRunFunction run_mesh = nullptr;     // meshes
  PointRunFunction run_points = nullptr;  // points
};

// Every algorithm: mesh algorithms first, then point algorithms, each in wire order.
std::span<const AlgorithmInfo> Algorithms();

const AlgorithmInfo* FindAlgorithm(InputKind input, absl::string_view name);
const AlgorithmInfo* FindAlgorithmByWire(InputKind input, int wire);
// What a job that names no algorithm runs: ML for meshes (the dissertation's method) and
// for points.
const AlgorithmInfo& DefaultAlgorithm(InputKind input);

// The names of `input`'s algorithms / energies, joined with ", " (for "available: ...").
std::string AlgorithmNames(InputKind input);
std::string EnergyNames(InputKind input);

// The options `algorithm` accepts: its own, then (meshes) the energy options.
std::vector<const OptionInfo*> AlgorithmOptions(const AlgorithmInfo& algorithm);
// The option `name` of `algorithm` (its own or an energy option), or nullptr.
const OptionInfo* FindOption(const AlgorithmInfo& algorithm, absl::string_view name);

// ---------------------------------------------------------------------------------------
// Planning a job.

struct JobRequest {
  const AlgorithmInfo* algorithm = nullptr;  // required
  const EnergyInfo* energy = nullptr;        // nullptr: the algorithm's default
  // k for single-level algorithms; for hierarchies the lowest cluster count to compute
  // (0 = down to one).
  uint32_t clusters = 0;
  // Hierarchies only: the level range the caller wants (0 = no bound).
  uint32_t levels_high = 0, levels_low = 0;
  uint64_t seed = 1;
  std::vector<std::pair<std::string, std::string>> options;  // by name, as text
  DeviceChoice device = DeviceChoice::kAuto;
};

// Everything an algorithm reads: the defaults of every options struct, then the request's
// options applied.
struct JobPlan {
  const AlgorithmInfo* algorithm = nullptr;
  const EnergyInfo* energy = nullptr;
  uint32_t clusters = 0;
  uint64_t seed = 1;
  DeviceChoice device = DeviceChoice::kAuto;
  std::vector<StagePlan> stages;  // PlanDevices (core/plan/device_policy.h) fills it

  // Meshes.
  MeshEnergyOptions mesh_energy;
  SeedOptions seeds;
  EmloOptions emlo;
  BoundaryBasedOptions boundary_based;
  // BB's preset "patches" (ours, core/cluster/patches.h); threads and guard from
  // boundary_based.
  bool bb_patches = false;
  PatchOptions patches;
  MultilevelOptions multilevel;  // HC, ML, PML
  VsaOptions vsa;

  // Points.
  PointMultilevelOptions point_multilevel;  // HC, ML, PML
  enum class PointInit { kKmeansPlusPlus, kRandom, kGrid };
  PointInit point_init = PointInit::kKmeansPlusPlus;  // LN k-means, k-means
  uint32_t grid = 0;                                  // LN k-means with init grid
  LnKmeansOptions ln_kmeans;
  KmeansOptions kmeans;
  XmeansOptions xmeans;
  BisectingKmeansOptions bisecting;
};

// Checks the request against the registry and builds the plan: the energy is one the
// algorithm runs; every option is one it accepts (INVALID_ARGUMENT "option NAME is not
// known for ALGO" otherwise) and in range; clusters >= 1 for single-level algorithms.
// Does not plan devices (core/plan/device_policy.h PlanDevices) and does not know the input's size
// (the caller checks clusters against it).
absl::StatusOr<JobPlan> PlanJob(const JobRequest& request);

// The stage `name` / `stage` of the plan (nullptr if the plan has none).
const StagePlan* FindStage(const JobPlan& plan, absl::string_view name);
const StagePlan* FindStage(const JobPlan& plan, PlanStage stage);

}  // namespace mlclust

#endif  // MLCLUST_CORE_CLUSTER_REGISTRY_H_
