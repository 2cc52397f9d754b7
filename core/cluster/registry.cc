#include "core/cluster/registry.h"

#include <algorithm>
#include <cmath>
#include <set>

#include "absl/strings/ascii.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "core/base/random.h"
#include "core/base/status_macros.h"
#include "core/cluster/device_stages.h"

namespace mlclust {
namespace {

// ---------------------------------------------------------------------------------------
// Option builders.

using Apply = std::function<void(const OptionValue&, JobPlan&)>;

OptionInfo Choice(std::string name, std::vector<std::string> choices, std::string default_text,
                  std::string help, Apply apply) {
  OptionInfo option;
  option.name = std::move(name);
  option.type = OptionInfo::Type::kChoice;
  option.choices = std::move(choices);
  option.default_text = std::move(default_text);
  option.help = std::move(help);
  option.apply = std::move(apply);
  return option;
}

OptionInfo Integer(std::string name, int64_t low, int64_t high, std::string default_text,
                   std::string help, Apply apply) {
  OptionInfo option;
  option.name = std::move(name);
  option.type = OptionInfo::Type::kInteger;
  option.low = static_cast<double>(low);
  option.high = static_cast<double>(high);
  option.default_text = std::move(default_text);
  option.help = std::move(help);
  option.apply = std::move(apply);
  return option;
}

OptionInfo Number(std::string name, double low, double high, std::string default_text,
                  std::string help, Apply apply) {
  OptionInfo option;
  option.name = std::move(name);
  option.type = OptionInfo::Type::kNumber;
  option.low = low;
  option.high = high;
  option.default_text = std::move(default_text);
  option.help = std::move(help);
  option.apply = std::move(apply);
  return option;
}

// `option` with its default marked as the text's.
OptionInfo Texts(OptionInfo option) {
  option.default_origin = OptionInfo::Origin::kText;
  return option;
}

// `option` with its default marked as ours; `text_variant` the text's value, which the preset
// dissertation sets ("": the text leaves it to the user, so the preset needs it given).
OptionInfo Ours(OptionInfo option, std::string text_variant) {
  option.default_origin = OptionInfo::Origin::kOurs;
  option.text_variant = std::move(text_variant);
  return option;
}

// The option "preset" of an algorithm that has no other preset: none, or the text's variants.
OptionInfo DissertationPresetOption() {
  return Choice("preset", {"none", kDissertationPreset}, "none", "",
                [](const OptionValue&, JobPlan&) {});  // PlanJob applies it; help: below
}

// Options several algorithms share, each writing its own field.
// `vertex_count`: the driver can run Alg. 3.2 (EMLO and BB with kept counts; ML's local
// optimisation without, as a merge relabels whole clusters).
OptionInfo GuardOption(std::string help_target, bool vertex_count = false) {
  std::vector<std::string> choices = {"on", "ring", "off"};
  if (vertex_count) choices.push_back("vertex-count");
  OptionInfo option = Choice(
      "guard", std::move(choices), "on",
      absl::StrCat("the connectivity guard: no cluster splits or gains a hole (", help_target,
                   "); on = ring, ours: the faces around a face in its cluster and in the "
                   "target each form one run",
                   vertex_count ? "; vertex-count: Alg. 3.2's vertex boundary-edge counts "
                                  "(l. 870-890)"
                                : "",
                   "; off: none"),
      [](const OptionValue& v, JobPlan& plan) {
        const bool on = v.text != "off";
        const ConnectivityGuardKind kind = v.text == "vertex-count"
                                               ? ConnectivityGuardKind::kVertexBoundaryEdgeCount
                                           : on ? ConnectivityGuardKind::kRingTest
                                                : ConnectivityGuardKind::kOff;
        plan.multilevel.connectivity_guard = on;
        plan.multilevel.guard = kind;
        plan.emlo.connectivity_guard = on;
        plan.emlo.guard = kind;
        plan.boundary_based.connectivity_guard = on;
        plan.boundary_based.guard = kind;
      });
  // The text embeds Alg. 3.2's check in its optimisers (l. 937).
  return vertex_count ? Ours(std::move(option), "vertex-count") : option;
}

OptionInfo ThreadsOption(std::string what, void (*set)(JobPlan&, int)) {
  return Integer(
      "threads", 0, 1024, "0", absl::StrCat(what, " worker threads, 0 = all cores"),
      [set](const OptionValue& v, JobPlan& plan) { set(plan, static_cast<int>(v.integer)); });
}

OptionInfo MeshOptimizerOption() {
  return Choice("optimizer", {"emlo", "bb", "none"}, "emlo",
                "the local optimiser after each merge: EMLO (Alg. 3.3), boundary-based sweeps "
                "(Alg. 5.1) or none (merges only)",
                [](const OptionValue& v, JobPlan& plan) {
                  plan.multilevel.optimizer =
                      v.text == "bb"     ? MultilevelOptions::Optimizer::kBoundaryBased
                      : v.text == "none" ? MultilevelOptions::Optimizer::kNone
                                         : MultilevelOptions::Optimizer::kEmlo;
                });
}

OptionInfo PPercentOption() {
  return Number("p-percent", 0, 100, "0",
                "merge this % of the clusters first without optimising, then ML (Alg. 4.2; "
                "0 = plain ML; how: p-percent-rule)",
                [](const OptionValue& v, JobPlan& plan) { plan.multilevel.p_percent = v.number; });
}

OptionInfo PPercentRuleOption() {
  return Texts(
      Choice("p-percent-rule", {"sweep", "hc-first"}, "sweep",
             "how the first p% merge: one sequential sweep collapsing non-conflicting optimal "
             "dual edges (Alg. 4.2) or, ours, one level per merge, cheapest first, as HC",
             [](const OptionValue& v, JobPlan& plan) {
               plan.multilevel.p_percent_rule = v.text == "hc-first"
                                                    ? MultilevelOptions::PPercentRule::kHcFirst
                                                    : MultilevelOptions::PPercentRule::kSweep;
             }));
}

OptionInfo PmlUntilOption(bool points) {
  return Integer("pml-until", 0, int64_t{1} << 31, "0",
                 "PML while more than this many clusters are left, then ML (0 = PML to the end)",
                 [points](const OptionValue& v, JobPlan& plan) {
                   if (points) {
                     plan.point_multilevel.pml_until = static_cast<uint32_t>(v.integer);
                   } else {
                     plan.multilevel.pml_until = static_cast<uint32_t>(v.integer);
                   }
                 });
}

// The PML pair rule (core/cluster/detail/pml_pairs.h), for meshes and points alike.
OptionInfo PmlPairsOption() {
  return Ours(
      Choice("pml-pairs", {"cheaper-half", "all"}, "cheaper-half",
             "the mutual pairs a PML level collapses: all of them (Alg. 5.3) or, ours, those "
             "at most the level's median cost (the default by measurement: BENCHMARKS.md)",
             [](const OptionValue& v, JobPlan& plan) {
               const PmlPairRule rule =
                   v.text == "all" ? PmlPairRule::kAll : PmlPairRule::kCheaperHalf;
               plan.multilevel.pml_pairs = rule;
               plan.point_multilevel.pml_pairs = rule;
             }),
      "all");
}

// MultilevelOptions::parallel_optimisation and independent_moves (ours), for the mesh PML.
OptionInfo ParallelOptimisationOption() {
  return Texts(Choice(
      "parallel-optimisation", {"off", "rounds", "independent"}, "off",
      "ours: a PML level's local optimisation (EMLO only) in parallel rounds instead of EMLO's "
      "one queue, every boundary face finding its best move at once; rounds: the moves then "
      "checked again and applied in face order with the guard; independent: a set of moves "
      "on pairwise disjoint clusters, guard-checked and applied in parallel, the rest next "
      "round, the level going on in face order once a round has few winners. Other levels "
      "than EMLO's, the same on any thread count",
      [](const OptionValue& v, JobPlan& plan) {
        plan.multilevel.parallel_optimisation = v.text != "off";
        plan.multilevel.independent_moves = v.text == "independent";
      }));
}

// PML's preset "many-cores" (ours, issue 10): the configuration measured best for many CPU
// cores (BENCHMARKS.md, "The preset many-cores and its 16-core bound"). Listed last, so it sets
// what it names over those options.
OptionInfo PmlPresetOption() {
  return Choice("preset", {"none", "many-cores", kDissertationPreset}, "none",
                "ours: many-cores = PML for many CPU cores: the first 95% of the merges "
                "unoptimised (p-percent 95, p-percent-rule hc-first; optimised at least below "
                "2 pml-until clusters), PML down to max(clusters, 1000) then ML (pml-until), "
                "the local optimisation in parallel rounds (parallel-optimisation rounds); "
                "overrides those four options",
                [](const OptionValue& v, JobPlan& plan) {
                  if (v.text != "many-cores") return;
                  plan.multilevel.p_percent = 95;
                  plan.multilevel.p_percent_rule = MultilevelOptions::PPercentRule::kHcFirst;
                  plan.multilevel.pml_until = std::max<uint32_t>(plan.clusters, 1000);
                  plan.multilevel.optimise_below_at_least = 2 * plan.multilevel.pml_until;
                  plan.multilevel.parallel_optimisation = true;
                  plan.multilevel.independent_moves = false;
                });
}

OptionInfo SeedInitOption() {
  return Texts(Choice("init", {"lneigh", "random"}, "lneigh",
                      "initial seeds: l-neighbourhood seeds (Alg. 3.1) or random faces, grown as "
                      "--growth says",
                      [](const OptionValue& v, JobPlan& plan) {
                        plan.seeds.method = v.text == "random"
                                                ? SeedOptions::Method::kRandom
                                                : SeedOptions::Method::kLNeighbourhood;
                      }));
}

OptionInfo SeedGrowthOption() {
  return Ours(
      Choice("growth", {"flood", "free", "rounds"}, "flood",
             "how seeds grow into clusters: the energy-ordered flood (Alg. 2.2; the CVD "
             "energies by distance to the seed) or energy-free, each cluster in turn taking "
             "the free faces across its boundary (l. 671, 1219), or rounds: section 5.2's "
             "growth (Fig. 5.9), each round every free face next to clusters joining the one "
             "with the smallest id: the same partition as free (proven in "
             "mesh_clustering.cc); with --device gpu it runs as rounds on the GPU",
             [](const OptionValue& v, JobPlan& plan) {
               plan.seeds.growth = v.text == "free"     ? SeedOptions::Growth::kEnergyFree
                                   : v.text == "rounds" ? SeedOptions::Growth::kRounds
                                                        : SeedOptions::Growth::kEnergyOrdered;
             }),
      "free");
}

OptionInfo SeedReductionOption() {
  return Ours(Choice("seed-reduction", {"merge", "reseed"}, "merge",
                     "l-neighbourhood seeds above k: merge the three clusters at the vertex with "
                     "the smallest summed area, keeping the grown regions (ours) or re-seeding at "
                     "that common vertex and growing all seeds again (l. 849)",
                     [](const OptionValue& v, JobPlan& plan) {
                       plan.seeds.reduction = v.text == "reseed"
                                                  ? SeedOptions::Reduction::kReseedAndRegrow
                                                  : SeedOptions::Reduction::kMergeRegions;
                     }),
              "reseed");
}

OptionInfo AddSeedsOption() {
  return Choice("add-seeds", {"off", "on"}, "off",
                "l-neighbourhood seeds below k (a large --level): refuse, or add seeds at the "
                "common vertex of three neighbouring clusters and grow again (l. 849)",
                [](const OptionValue& v, JobPlan& plan) { plan.seeds.add_seeds = v.text == "on"; });
}

OptionInfo SeedLevelOption() {
  return Integer("level", 0, int64_t{1} << 20, "0",
                 "l of the l-neighbourhood seeds (Alg. 3.1); 0 = the largest l that still gives "
                 "k seeds",
                 [](const OptionValue& v, JobPlan& plan) {
                   plan.seeds.level = static_cast<uint32_t>(v.integer);
                 });
}

OptionInfo GridOption(std::string help) {
  // The text's a is the user's (section 6.2, l. 2605): the preset dissertation needs it given.
  return Ours(Integer("grid", 0, int64_t{1} << 20, "0", std::move(help),
                      [](const OptionValue& v, JobPlan& plan) {
                        plan.point_multilevel.grid = static_cast<uint32_t>(v.integer);
                        plan.grid = static_cast<uint32_t>(v.integer);
                      }),
              "");
}

OptionInfo PointOptimizerOption() {
  return Choice("optimizer", {"lnkmeans", "none"}, "lnkmeans",
                "the local optimiser after each merge: LN k-means (Alg. 6.1) or none",
                [](const OptionValue& v, JobPlan& plan) {
                  plan.point_multilevel.optimizer =
                      v.text == "none" ? PointMultilevelOptions::Optimizer::kNone
                                       : PointMultilevelOptions::Optimizer::kLnKmeans;
                });
}

// BB's preset "patches", ours: meshlet-sized patches fast (core/cluster/patches.h).
std::vector<OptionInfo> PatchPresetOptions() {
  return {
      Choice("preset", {"none", "patches", kDissertationPreset}, "none",
             "ours: patches = many small connected patches fast (e.g. K = faces / 124, GPU "
             "meshlets): Morton-order seeds, energy-free growth, Lloyd steps on the seeds "
             "(patch-reseeds), then at most patch-sweeps BB sweeps applied in face order (on "
             "the CPU); init, level, seed-reduction, add-seeds and max-iterations do not "
             "apply; growth rounds grows (the same partition) on the GPU where the seed stage "
             "is",
             [](const OptionValue& v, JobPlan& plan) { plan.bb_patches = v.text == "patches"; }),
      Integer("patch-sweeps", 0, 1000000, "6", "preset patches: BB sweeps at most",
              [](const OptionValue& v, JobPlan& plan) {
                plan.patches.sweeps = static_cast<uint32_t>(v.integer);
              }),
      Integer("patch-reseeds", 0, 1000, "1",
              "preset patches: Lloyd steps on the seeds (each to its cluster's face nearest "
              "the centroid, all grown again) before the sweeps",
              [](const OptionValue& v, JobPlan& plan) {
                plan.patches.reseeds = static_cast<uint32_t>(v.integer);
              }),
  };
}

// PointMultilevelOptions::start, for the point hierarchies (HC, ML, PML).
OptionInfo PointStartOption() {
  return Ours(Choice("start", {"grid", "optimised-grid"}, "grid",
                     "level 0: the voxel clusters (grid, ours) or LN k-means on them first "
                     "(optimised-grid, the text's start of Fig. 6.5 / 6.8; CPU only)",
                     [](const OptionValue& v, JobPlan& plan) {
                       plan.point_multilevel.start =
                           v.text == "optimised-grid"
                               ? PointMultilevelOptions::Start::kOptimisedGrid
                               : PointMultilevelOptions::Start::kGrid;
                     }),
              "optimised-grid");
}

// PointMultilevelOptions::bounded_drift (ours), for ML/PML on points.
OptionInfo BoundedDriftOption() {
  return Texts(Number(
      "bounded-drift", 0, 1, "0",
      "ours: in LN k-means' later rounds after a merge, a changed cluster whose "
      "centroid moved by less than this share of its RMS radius keeps its points not "
      "yet checked in the level unchecked (0 = off: every one checked, as defined); "
      "e.g. 0.03: far less time on large sets at a slightly higher energy "
      "(BENCHMARKS.md, ML for points: bounded_drift)",
      [](const OptionValue& v, JobPlan& plan) { plan.point_multilevel.bounded_drift = v.number; }));
}

constexpr char kHierarchyGridHelp[] =
    "voxels per dimension of the start (section 6.2); 0 = aiming at about eight points per "
    "occupied cell";

void SetPointThreads(JobPlan& plan, int threads) {
  plan.point_multilevel.threads = threads;
  plan.ln_kmeans.threads = threads;
  plan.kmeans.threads = threads;
  plan.xmeans.threads = threads;
  plan.bisecting.threads = threads;
}

// ---------------------------------------------------------------------------------------
// Run functions.

// The plan's `stage` (on the CPU where the plan has none: a plan not yet given devices).
StagePlan Stage(const JobPlan& plan, PlanStage stage) {
  const StagePlan* found = FindStage(plan, stage);
  return found != nullptr ? *found : StagePlan{stage, StageDevice::kCpu, ""};
}

void Report(const RunContext& context, const JobPlan& plan, PlanStage stage,
            const std::string& message) {
  if (context.on_stage) context.on_stage(Stage(plan, stage), message);
}

// A single-level algorithm's result as two levels: level 0 the initial clusters
// (`initial_clusters` of them), level 1 the elements whose cluster the algorithm changed
// (`clusters` in all).
absl::Status EmitTwoLevels(std::span<const ClusterId> initial, uint32_t initial_clusters,
                           double initial_energy, std::span<const ClusterId> result, double energy,
                           uint32_t clusters, LevelSink& sink) {
  MLCLUST_RETURN_IF_ERROR(sink.OnStart(initial, initial_clusters, initial_energy));
  std::vector<uint32_t> element, to, from;
  for (uint32_t i = 0; i < result.size(); ++i) {
    if (result[i] != initial[i]) {
      element.push_back(i);
      to.push_back(result[i].value());
      from.push_back(initial[i].value());
    }
  }
  LevelMoves level;
  level.level = 1;
  level.cluster_count = clusters;
  level.energy = energy;
  level.element = element;
  level.to_cluster = to;
  level.from_cluster = from;
  return sink.OnLevel(level);
}

// The seeding at K, then the result at K.
absl::Status EmitSingleLevel(std::span<const ClusterId> initial, double initial_energy,
                             std::span<const ClusterId> result, double energy, uint32_t clusters,
                             LevelSink& sink) {
  return EmitTwoLevels(initial, clusters, initial_energy, result, energy, clusters, sink);
}

std::string EnergyNote(const JobPlan& plan) {
  return absl::StrCat(" (", plan.energy != nullptr ? plan.energy->name : "?", ")");
}

absl::StatusOr<RunSummary> RunMeshHierarchy(const MeshProblem& problem, const JobPlan& plan,
                                            LevelSink& sink, const RunContext& context) {
  Report(context, plan, PlanStage::kCluster, absl::StrCat(plan.algorithm->name, EnergyNote(plan)));
  MultilevelOptions options = plan.multilevel;
  options.cancel = context.cancel;
  absl::StatusOr<MultilevelSummary> ran;
  if (Stage(plan, PlanStage::kCluster).device == StageDevice::kGpu) {
    // PML's levels, HC's steps or ML's (core/plan/device_policy.h says which plans).
    if (context.devices == nullptr) {
      return absl::FailedPreconditionError(
          "the plan puts the cluster stage on the GPU but this run has no GPU stages");
    }
    ran = options.parallel ? context.devices->RunMultilevel(problem, options, sink)
                           : context.devices->RunHierarchy(problem, options, sink);
  } else {
    ran = RunMultilevel(problem, options, sink);
  }
  MLCLUST_ASSIGN_OR_RETURN(MultilevelSummary summary, std::move(ran));
  return RunSummary{static_cast<uint32_t>(problem.mesh->num_faces()), summary.final_clusters};
}

// Whether the plan puts the seed stage's growth on the GPU; reports `message` on the stage.
bool SeedGrowsOnGpu(const JobPlan& plan, const RunContext& context, const std::string& message) {
  Report(context, plan, PlanStage::kSeed, message);
  return Stage(plan, PlanStage::kSeed).device == StageDevice::kGpu;
}

// The device's growth rounds for a seed stage the plan put on the GPU.
absl::StatusOr<SeedOptions::DeviceGrowth> DeviceRoundsGrowth(const RunContext& context) {
  SeedOptions::DeviceGrowth growth;
  if (context.devices != nullptr) growth = context.devices->RoundsGrowth();
  if (!growth) {
    return absl::FailedPreconditionError(
        "the plan puts the seed stage's growth on the GPU but this run has no GPU stages");
  }
  return growth;
}

// BB's preset "patches" (core/cluster/patches.h): level 0 the grown seeds, level 1 the
// swept patches.
absl::StatusOr<RunSummary> RunMeshPatches(const MeshProblem& problem, const JobPlan& plan,
                                          LevelSink& sink, const RunContext& context) {
  if (plan.boundary_based.connectivity_guard &&
      plan.boundary_based.guard == ConnectivityGuardKind::kVertexBoundaryEdgeCount) {
    return absl::InvalidArgumentError(
        "guard: preset patches checks moves with the ring test (on) or not at all (off), not "
        "vertex-count");
  }
  PatchOptions options = plan.patches;
  options.clusters = plan.clusters;
  options.threads = plan.boundary_based.threads;
  options.guard = plan.boundary_based.connectivity_guard ? ConnectivityGuardKind::kRingTest
                                                         : ConnectivityGuardKind::kOff;
  options.cancel = context.cancel;
  if (SeedGrowsOnGpu(
          plan, context,
          absl::StrCat(plan.clusters, " spread seeds grown (", options.reseeds, " Lloyd steps)"))) {
    // The energy-free growth is growth rounds' partition: grown as rounds on the GPU.
    options.growth = SeedOptions::Growth::kRounds;
    MLCLUST_ASSIGN_OR_RETURN(options.device_rounds, DeviceRoundsGrowth(context));
  }
  Report(context, plan, PlanStage::kCluster,
         absl::StrCat("patches: at most ", options.sweeps, " BB sweeps", EnergyNote(plan)));
  MLCLUST_ASSIGN_OR_RETURN(PatchResult result, BuildPatches(problem, options));
  MLCLUST_RETURN_IF_ERROR(EmitSingleLevel(result.initial_labels, result.initial_energy,
                                          result.labels, result.energy, plan.clusters, sink));
  return RunSummary{plan.clusters, plan.clusters};
}

absl::StatusOr<RunSummary> RunMeshLocal(const MeshProblem& problem, const JobPlan& plan,
                                        LevelSink& sink, const RunContext& context) {
  if (plan.bb_patches && plan.algorithm->name == "bb") {
    return RunMeshPatches(problem, plan, sink, context);
  }
  const bool seed_on_gpu =
      SeedGrowsOnGpu(plan, context, absl::StrCat(plan.clusters, " initial clusters"));
  SeedOptions seeds = plan.seeds;
  seeds.cancel = context.cancel;
  if (seed_on_gpu) {
    MLCLUST_ASSIGN_OR_RETURN(seeds.device_rounds, DeviceRoundsGrowth(context));
  }
  MLCLUST_ASSIGN_OR_RETURN(std::vector<ClusterId> initial, InitialClusters(problem, seeds));
  std::vector<ClusterId> labels = initial;
  absl::StatusOr<OptimizeResult> result;
  if (plan.algorithm->name == "emlo") {
    Report(context, plan, PlanStage::kCluster, absl::StrCat("EMLO", EnergyNote(plan)));
    result = OptimizeEmlo(problem, labels, plan.emlo);
  } else {
    Report(context, plan, PlanStage::kCluster, absl::StrCat("boundary-based", EnergyNote(plan)));
    BoundaryBasedOptions options = plan.boundary_based;
    options.cancel = context.cancel;
    options.on_iteration = [&](uint32_t iteration, double energy) {
      Report(context, plan, PlanStage::kCluster,
             absl::StrCat("sweep ", iteration, ": energy ", energy));
    };
    if (Stage(plan, PlanStage::kCluster).device == StageDevice::kGpu) {
      if (context.devices == nullptr) {
        return absl::FailedPreconditionError(
            "BB: the plan puts the decide stage on the GPU but this run has no GPU stages");
      }
      result = context.devices->OptimizeBoundaryBased(problem, labels, options);
    } else {
      result = OptimizeBoundaryBased(problem, labels, options);
    }
  }
  if (!result.ok()) return result.status();
  MLCLUST_RETURN_IF_ERROR(EmitSingleLevel(initial, result->initial_energy, labels, result->energy,
                                          plan.clusters, sink));
  return RunSummary{plan.clusters, plan.clusters};
}

absl::StatusOr<RunSummary> RunMeshVsa(const MeshProblem& problem, const JobPlan& plan,
                                      LevelSink& sink, const RunContext& context) {
  // Level 0 is the seeding's partition (VsaResult::initial_labels), the last level the
  // result.
  Report(context, plan, PlanStage::kSeed, absl::StrCat(plan.clusters, " initial regions"));
  Report(context, plan, PlanStage::kCluster, absl::StrCat("VSA", EnergyNote(plan)));
  VsaOptions options = plan.vsa;
  // Without min-relative-decrease every iteration runs, so the share done is known.
  const bool fixed_count = plan.vsa.min_relative_decrease == 0 && plan.vsa.iterations > 0;
  options.on_iteration = [&](uint32_t iteration, double energy) {
    const std::string message = absl::StrCat("iteration ", iteration, ": energy ", energy);
    if (fixed_count && context.on_fraction) {
      context.on_fraction(Stage(plan, PlanStage::kCluster),
                          std::min(1.0, static_cast<double>(iteration) / plan.vsa.iterations),
                          message);
    } else {
      Report(context, plan, PlanStage::kCluster, message);
    }
  };
  MLCLUST_ASSIGN_OR_RETURN(VsaResult result, RunVsa(problem, options));
  MLCLUST_RETURN_IF_ERROR(EmitSingleLevel(result.initial_labels, result.initial_energy,
                                          result.labels, result.energy, plan.clusters, sink));
  return RunSummary{plan.clusters, plan.clusters};
}

absl::StatusOr<RunSummary> RunPointHierarchy(const PointSet& points, const JobPlan& plan,
                                             LevelSink& sink, const RunContext& context) {
  Report(context, plan, PlanStage::kCluster,
         absl::StrCat(points.num_points(), " points in ", points.dims,
                      " dimensions: ", plan.algorithm->name));
  PointMultilevelOptions options = plan.point_multilevel;
  options.cancel = context.cancel;
  absl::StatusOr<PointMultilevelSummary> ran;
  const bool on_gpu = Stage(plan, PlanStage::kCluster).device == StageDevice::kGpu;
  if (on_gpu) {
    // PML's levels or HC's and ML's steps for points on the GPU.
    if (context.devices == nullptr) {
      return absl::FailedPreconditionError(
          "the plan puts the point levels on the GPU but this run has no GPU stages");
    }
    ran = context.devices->RunPointMultilevel(points, options, sink);
  } else {
    ran = RunPointMultilevel(points, options, sink);
  }
  MLCLUST_ASSIGN_OR_RETURN(PointMultilevelSummary summary, std::move(ran));
  return RunSummary{summary.start_clusters, summary.final_clusters};
}

absl::StatusOr<RunSummary> RunPointLnKmeans(const PointSet& points, const JobPlan& plan,
                                            LevelSink& sink, const RunContext& context) {
  Report(context, plan, PlanStage::kCluster,
         absl::StrCat(points.num_points(), " points in ", points.dims,
                      " dimensions: ", plan.algorithm->name));
  if (plan.point_init == JobPlan::PointInit::kGrid) {
    // From the voxel grid: level 0 is the voxel clusters, level 1 the result.
    LnKmeansOptions options = plan.ln_kmeans;
    options.cancel = context.cancel;
    MLCLUST_ASSIGN_OR_RETURN(VoxelStart start, VoxelGridStart(points, plan.grid, context.cancel));
    MLCLUST_ASSIGN_OR_RETURN(LnKmeansResult result,
                             RunLnKmeansFromGrid(points, plan.grid, options));
    MLCLUST_RETURN_IF_ERROR(EmitSingleLevel(start.labels, result.initial_energy, result.labels,
                                            result.energy, start.clusters, sink));
    return RunSummary{start.clusters, start.clusters};
  }
  MLCLUST_ASSIGN_OR_RETURN(std::vector<ClusterId> initial,
                           SeedPointClusters(points, plan.clusters,
                                             plan.point_init == JobPlan::PointInit::kKmeansPlusPlus,
                                             plan.seed, plan.ln_kmeans.threads));
  LnKmeansOptions options = plan.ln_kmeans;
  options.cancel = context.cancel;
  absl::StatusOr<LnKmeansResult> ran;
  if (Stage(plan, PlanStage::kCluster).device == StageDevice::kGpu) {
    if (context.devices == nullptr) {
      return absl::FailedPreconditionError(
          "LN k-means: the plan puts the assign stage on the GPU but this run has no GPU stages");
    }
    ran = context.devices->RunLnKmeans(points, initial, options);
  } else {
    ran = RunLnKmeans(points, initial, options);
  }
  if (!ran.ok()) return ran.status();
  const LnKmeansResult& result = *ran;
  MLCLUST_RETURN_IF_ERROR(EmitSingleLevel(initial, result.initial_energy, result.labels,
                                          result.energy, plan.clusters, sink));
  return RunSummary{plan.clusters, plan.clusters};
}

absl::StatusOr<RunSummary> RunPointKmeans(const PointSet& points, const JobPlan& plan,
                                          LevelSink& sink, const RunContext& context) {
  Report(context, plan, PlanStage::kCluster,
         absl::StrCat(points.num_points(), " points in ", points.dims,
                      " dimensions: ", plan.algorithm->name));
  // Lloyd from k-means++ (or random) centres. Level 0 is the seeding: every point at its
  // nearest initial centre, Lloyd's first assignment (KmeansOptions::keep_first_assignment,
  // on either device: the GPU's Lloyd is the CPU's loop with another assignment step).
  const bool plus_plus = plan.point_init == JobPlan::PointInit::kKmeansPlusPlus;
  const bool on_gpu = Stage(plan, PlanStage::kCluster).device == StageDevice::kGpu;
  if (on_gpu && context.devices == nullptr) {
    return absl::FailedPreconditionError(
        "k-means: the plan puts the assignment on the GPU but this run has no GPU stages");
  }
  auto lloyd = [&](std::vector<float> start_centres,
                   const KmeansOptions& options) -> absl::StatusOr<KmeansResult> {
    if (on_gpu) return context.devices->RunLloyd(points, std::move(start_centres), options);
    return RunLloyd(points, std::move(start_centres), options);
  };
  if (plan.point_init == JobPlan::PointInit::kGrid) {
    // From the voxel grid (Fig. 6.11's equal start with LN k-means): the centres are the
    // means of the occupied voxels' points; level 0 is the voxel clusters, level 1 the result.
    MLCLUST_ASSIGN_OR_RETURN(VoxelStart start, VoxelGridStart(points, plan.grid, context.cancel));
    const uint32_t d = points.dims;
    std::vector<double> sums(size_t{start.clusters} * d, 0.0);
    std::vector<uint64_t> counts(start.clusters, 0);
    for (size_t i = 0; i < points.num_points(); ++i) {
      const uint32_t c = start.labels[i].value();
      const std::span<const float> p = points.point(PointId(static_cast<uint32_t>(i)));
      for (uint32_t j = 0; j < d; ++j) sums[size_t{c} * d + j] += p[j];
      ++counts[c];
    }
    std::vector<float> centres(sums.size());
    for (size_t v = 0; v < sums.size(); ++v) {
      centres[v] = static_cast<float>(sums[v] / static_cast<double>(counts[v / d]));
    }
    KmeansOptions options = plan.kmeans;
    options.clusters = start.clusters;
    options.on_iteration = [&](uint32_t iteration, double inertia) {
      Report(context, plan, PlanStage::kCluster,
             absl::StrCat("iteration ", iteration, ": energy ", inertia));
    };
    MLCLUST_ASSIGN_OR_RETURN(KmeansResult result, lloyd(std::move(centres), options));
    MLCLUST_RETURN_IF_ERROR(EmitSingleLevel(start.labels, PointEnergy(points, start.labels),
                                            result.labels, result.inertia, start.clusters, sink));
    return RunSummary{start.clusters, start.clusters};
  }
  MLCLUST_ASSIGN_OR_RETURN(
      std::vector<float> centres,
      plus_plus ? KmeansPlusPlusCentres(points, plan.clusters, plan.seed, plan.kmeans.threads)
                : RandomPointCentres(points, plan.clusters, plan.seed));
  KmeansOptions options = plan.kmeans;
  options.clusters = plan.clusters;
  options.keep_first_assignment = true;
  options.on_iteration = [&](uint32_t iteration, double inertia) {
    Report(context, plan, PlanStage::kCluster,
           absl::StrCat("iteration ", iteration, ": energy ", inertia));
  };
  MLCLUST_ASSIGN_OR_RETURN(KmeansResult result, lloyd(std::move(centres), options));
  MLCLUST_RETURN_IF_ERROR(EmitSingleLevel(result.first_labels, result.first_inertia, result.labels,
                                          result.inertia, plan.clusters, sink));
  return RunSummary{plan.clusters, plan.clusters};
}

// X-means (Alg. 2.5): level 0 is its line 1, k-means at k_min (JobPlan::clusters), run again
// here as RunXmeans runs it (the same options and seed: the first draw of Random(seed)), since
// RunXmeans hands back only the chosen round; level 1 is the chosen model, with the number of
// clusters X-means found.
absl::StatusOr<RunSummary> RunPointXmeans(const PointSet& points, const JobPlan& plan,
                                          LevelSink& sink, const RunContext& context) {
  XmeansOptions options = plan.xmeans;
  options.min_clusters = plan.clusters;
  options.seed = plan.seed;
  options.cancel = context.cancel;
  Report(context, plan, PlanStage::kSeed,
         absl::StrCat(points.num_points(), " points in ", points.dims, " dimensions: k-means at ",
                      "k_min = ", options.min_clusters));
  KmeansOptions first = KmeansOptionsFor(options, options.min_clusters);
  first.seed = Random(options.seed).Next();
  MLCLUST_ASSIGN_OR_RETURN(KmeansResult start, RunKmeans(points, first));
  Report(context, plan, PlanStage::kCluster,
         absl::StrCat("X-means: virtual splits kept where the BIC rises, up to k_max = ",
                      options.max_clusters == 0 ? points.num_points() : options.max_clusters));
  MLCLUST_ASSIGN_OR_RETURN(XmeansResult result, RunXmeans(points, options));
  for (size_t r = 0; r < result.rounds.size(); ++r) {
    const XmeansRound& round = result.rounds[r];
    Report(context, plan, PlanStage::kCluster,
           absl::StrCat("round ", r, ": ", round.clusters, " clusters (", round.splits,
                        " splits), energy ", round.inertia, ", BIC ", round.bic,
                        r == result.chosen_round ? " (chosen: the largest BIC)" : ""));
  }
  MLCLUST_RETURN_IF_ERROR(EmitTwoLevels(start.labels, options.min_clusters, start.inertia,
                                        result.labels, result.inertia, result.clusters, sink));
  return RunSummary{options.min_clusters, result.clusters};
}

// Bisecting k-means (Alg. 2.7) down from K = JobPlan::clusters: level 0 is the K clusters,
// then the splits undone, last first, down to one cluster (EmitBisectingLevels).
absl::StatusOr<RunSummary> RunPointBisecting(const PointSet& points, const JobPlan& plan,
                                             LevelSink& sink, const RunContext& context) {
  BisectingKmeansOptions options = plan.bisecting;
  options.clusters = plan.clusters;
  options.seed = plan.seed;
  options.cancel = context.cancel;
  Report(context, plan, PlanStage::kCluster,
         absl::StrCat(points.num_points(), " points in ", points.dims,
                      " dimensions: bisecting k-means to ", options.clusters, " clusters"));
  MLCLUST_ASSIGN_OR_RETURN(BisectingKmeansResult result, RunBisectingKmeans(points, options));
  MLCLUST_RETURN_IF_ERROR(EmitBisectingLevels(result, sink));
  return RunSummary{static_cast<uint32_t>(result.splits.size() + 1), 1};
}

// ---------------------------------------------------------------------------------------
// The tables.

// Wire values (proto/mlclust/v1/mlclust.proto); server/wire_registry.h checks them.
enum WireAlgorithm {
  kWireHc = 1,
  kWireMl = 2,
  kWirePml = 3,
  kWireEmlo = 4,
  kWireBb = 5,
  kWireVsa = 6,
  kWireLnKmeans = 7,
  kWireKmeans = 8,
  kWireXmeans = 9,
  kWireBisecting = 10,
};

std::vector<EnergyInfo> BuildEnergies() {
  auto mesh = [](std::string name, int wire, MeshEnergyKind kind, std::string help) {
    return EnergyInfo{std::move(name), wire, InputKind::kMesh, kind, std::move(help)};
  };
  std::vector<EnergyInfo> energies = {
      mesh("cvd", 1, MeshEnergyKind::kCvd, "centroidal Voronoi diagram, uniform density (eq. 3.7)"),
      mesh("cvd-adaptive", 2, MeshEnergyKind::kCvdAdaptive,
           "CVD with the face density rho of section 3.2.1 (eqs. 3.7, 3.17)"),
      mesh("mwcvd-area", 3, MeshEnergyKind::kMwcvdArea,
           "multiplicatively weighted CVD with the area weight w^A (eqs. 3.23, 3.24)"),
      mesh("mwcvd-variance", 4, MeshEnergyKind::kMwcvdVariance,
           "multiplicatively weighted CVD with the variance weight w^V (eqs. 3.23, 3.27)"),
      mesh("mwcvd-max", 5, MeshEnergyKind::kMwcvdMax,
           "multiplicatively weighted CVD with the max weight w^M (eqs. 3.23, 3.28)"),
      mesh("planar", 6, MeshEnergyKind::kPlanar, "planar fit, L2,1 (eq. 3.38)"),
      mesh("sphere", 7, MeshEnergyKind::kSphere,
           "sphere fit (eqs. 3.40-3.46; planar clusters below Delta_zero, l. 1333)"),
      EnergyInfo{"variance", 8, InputKind::kPoints, MeshEnergyKind::kCvd,
                 "within-cluster sum of squared distances to the mean (section 6.5)"},
      mesh("sphere-normals", 0, MeshEnergyKind::kSphereNormals,
           "ours: least-squares fit of the normal field to a sphere (not on the wire yet)"),
  };
  return energies;
}

std::vector<OptionInfo> BuildEnergyOptions() {
  return {
      Choice("density", {"power", "linear"}, "linear for mwcvd-*, power for cvd-adaptive",
             "the face density mapping of cvd-adaptive and mwcvd-*: power (rho' + delta)^gamma "
             "(l. 931) or linear onto [1, rho-max] (l. 933)",
             [](const OptionValue& v, JobPlan& plan) {
               plan.mesh_energy.density.mapping = v.text == "linear"
                                                      ? DensityOptions::Mapping::kLinear
                                                      : DensityOptions::Mapping::kPower;
             }),
      Number(
          "gamma", 1e-6, 100, "2", "gamma of the power density mapping (l. 931)",
          [](const OptionValue& v, JobPlan& plan) { plan.mesh_energy.density.gamma = v.number; }),
      Number(
          "delta", 1e-12, 100, "0.01", "delta of the power density mapping (l. 931)",
          [](const OptionValue& v, JobPlan& plan) { plan.mesh_energy.density.delta = v.number; }),
      Number(
          "rho-max", 1.000001, 1e6,
          "50 for mwcvd-area and mwcvd-max, 3 for mwcvd-variance, 10 for cvd-adaptive",
          "rho^new, the upper end of the linear density mapping (l. 933; Table 3.1)",
          [](const OptionValue& v, JobPlan& plan) { plan.mesh_energy.density.rho_max = v.number; }),
      Number("mwcvd-p", 1, 64, "10", "p of the max weight w^M of mwcvd-max (eq. 3.28)",
             [](const OptionValue& v, JobPlan& plan) { plan.mesh_energy.mwcvd_p = v.number; }),
      Number("planar-tolerance", 0, 0.5, "5e-05",
             "Delta_zero of the sphere energy: a cluster with |k^2 - |sum n|^2| below it is "
             "planar (l. 1333)",
             [](const OptionValue& v, JobPlan& plan) {
               plan.mesh_energy.planar_tolerance = v.number;
             }),
  };
}

const std::vector<EnergyInfo>& EnergyTable() {
  static const auto* table = new std::vector<EnergyInfo>(BuildEnergies());
  return *table;
}

// Appends to `algorithm`'s option preset, where it offers dissertation, what that sets: every
// option whose default is ours, at the text's variant.
void DescribeDissertationPreset(AlgorithmInfo& algorithm) {
  OptionInfo* preset = nullptr;
  std::vector<std::string> sets;
  for (OptionInfo& option : algorithm.options) {
    if (option.name == "preset") preset = &option;
    if (option.default_origin != OptionInfo::Origin::kOurs) continue;
    sets.push_back(
        option.text_variant.empty()
            ? absl::StrCat(option.name, " given >= 1 where it applies (the text's is the user's)")
            : absl::StrCat(option.name, " ", option.text_variant));
  }
  if (preset == nullptr || std::find(preset->choices.begin(), preset->choices.end(),
                                     kDissertationPreset) == preset->choices.end()) {
    return;
  }
  absl::StrAppend(&preset->help, preset->help.empty() ? "" : "; ", kDissertationPreset,
                  " = the dissertation's variant wherever the default is ours: ",
                  absl::StrJoin(sets, ", "), "; an option given explicitly wins");
}

std::vector<AlgorithmInfo> BuildAlgorithms() {
  // The merge and local-optimisation drivers run every mesh energy (they need only an
  // energy's sums, merge cost, proxy and face cost), CVD first as the default.
  std::vector<std::string> mesh_energies;
  for (const EnergyInfo& energy : EnergyTable()) {
    if (energy.input == InputKind::kMesh) mesh_energies.push_back(energy.name);
  }
  const StageInfo merge_stage{"cluster", "merges (and local optimisation) level by level"};
  // With growth rounds the seeding's growth on the GPU (section 5.2,
  // gpu/stages/seed_growth_gpu.h), BB's preset patches' too (its energy-free growth is the
  // same partition).
  const StageInfo seed_stage{"seed", "k initial clusters (growth rounds on the GPU)"};
  std::vector<AlgorithmInfo> algorithms;

  // Meshes.
  {
    AlgorithmInfo a;
    a.name = "hc";
    a.wire = kWireHc;
    a.hierarchy = true;
    a.title = "hierarchical face clustering (Alg. 2.3)";
    a.help = "merges only: every level from one cluster per face down to --clusters";
    a.energies = mesh_energies;
    // HC's steps on the GPU (gpu/stages/hierarchy_gpu.h): CVD energies.
    a.stages = {merge_stage};
    a.run_mesh = RunMeshHierarchy;
    algorithms.push_back(a);
  }
  {
    AlgorithmInfo a;
    a.name = "ml";
    a.wire = kWireMl;
    a.hierarchy = true;
    a.title = "multilevel clustering (Alg. 4.1)";
    a.help = "merge the cheapest dual edge (eq. 4.1), then optimise locally; every level";
    a.energies = mesh_energies;
    a.options = {MeshOptimizerOption(), GuardOption("the optimiser's moves", /*vertex_count=*/true),
                 PPercentOption(), PPercentRuleOption(), DissertationPresetOption()};
    // ML's levels on the GPU (gpu/stages/multilevel_gpu.h): HC's steps or one merge and BB.
    a.stages = {merge_stage};
    a.run_mesh = RunMeshHierarchy;
    algorithms.push_back(a);
  }
  {
    AlgorithmInfo a;
    a.name = "pml";
    a.wire = kWirePml;
    a.hierarchy = true;
    a.title = "parallel multilevel clustering (Alg. 5.3)";
    a.help = "collapse all mutual optimal dual edges of a level at once, then optimise";
    a.energies = mesh_energies;
    a.options = {MeshOptimizerOption(),
                 GuardOption("the optimiser's moves", /*vertex_count=*/true),
                 PPercentOption(),
                 PPercentRuleOption(),
                 PmlUntilOption(false),
                 PmlPairsOption(),
                 ThreadsOption("PML", [](JobPlan& plan, int t) { plan.multilevel.threads = t; }),
                 ParallelOptimisationOption(),
                 PmlPresetOption()};
    // PML's levels on the GPU (gpu/stages/multilevel_gpu.h): merges only or with BB, CVD.
    a.stages = {merge_stage};
    a.run_mesh = RunMeshHierarchy;
    algorithms.push_back(a);
  }
  {
    AlgorithmInfo a;
    a.name = "emlo";
    a.wire = kWireEmlo;
    a.title = "energy minimisation by local optimisation (Alg. 3.3)";
    a.help = "seeds k clusters, then moves boundary faces while the energy falls";
    a.energies = mesh_energies;
    a.options = {SeedInitOption(),          SeedLevelOption(),
                 SeedGrowthOption(),        SeedReductionOption(),
                 AddSeedsOption(),          GuardOption("every move", /*vertex_count=*/true),
                 DissertationPresetOption()};
    a.stages = {seed_stage, {"cluster", "boundary moves until none lowers the energy"}};
    a.run_mesh = RunMeshLocal;
    algorithms.push_back(a);
  }
  {
    AlgorithmInfo a;
    a.name = "bb";
    a.wire = kWireBb;
    a.title = "boundary-based optimisation (Alg. 5.1)";
    a.help = "seeds k clusters, then parallel sweeps: every boundary face picks the best proxy";
    a.energies = mesh_energies;
    a.options = {SeedInitOption(),
                 SeedLevelOption(),
                 SeedGrowthOption(),
                 SeedReductionOption(),
                 AddSeedsOption(),
                 GuardOption("every move", /*vertex_count=*/true),
                 ThreadsOption("BB", [](JobPlan& plan, int t) { plan.boundary_based.threads = t; }),
                 Integer("max-iterations", 1, 1000000, "200", "BB sweeps at most",
                         [](const OptionValue& v, JobPlan& plan) {
                           plan.boundary_based.max_iterations = static_cast<uint32_t>(v.integer);
                         })};
    for (OptionInfo& option : PatchPresetOptions()) a.options.push_back(std::move(option));
    // The decide stage on the GPU (gpu/kernels/bb_decide.h) for the proxy-point energies,
    // HasGpuBoundaryDecide (core/plan/device_policy.h).
    a.stages = {seed_stage,
                {"cluster", "parallel sweeps with proxies fixed per sweep (decide on the GPU)"}};
    a.run_mesh = RunMeshLocal;
    algorithms.push_back(a);
  }
  {
    AlgorithmInfo a;
    a.name = "vsa";
    a.wire = kWireVsa;
    a.title = "variational shape approximation (Alg. 2.1-2.2)";
    a.help = "Lloyd on faces with the L2,1 metric (Cohen-Steiner et al. 2004), planar energy";
    a.energies = {"planar"};
    a.options = {
        Choice("init", {"hierarchical", "incremental", "random"}, "hierarchical",
               "seeding as CGAL's Surface_mesh_approximation (ours: farthest-first placement "
               "within a region)",
               [](const OptionValue& v, JobPlan& plan) {
                 plan.vsa.seeding = v.text == "random"        ? VsaOptions::Seeding::kRandom
                                    : v.text == "incremental" ? VsaOptions::Seeding::kIncremental
                                                              : VsaOptions::Seeding::kHierarchical;
               }),
        Integer("max-iterations", 0, 1000000, "30",
                "Lloyd iterations after seeding (0: the seeding's partition)",
                [](const OptionValue& v, JobPlan& plan) {
                  plan.vsa.iterations = static_cast<uint32_t>(v.integer);
                }),
        Integer("inner-iterations", 0, 1000000, "5", "Lloyd iterations after each seeding step",
                [](const OptionValue& v, JobPlan& plan) {
                  plan.vsa.inner_iterations = static_cast<uint32_t>(v.integer);
                }),
        Number(
            "min-relative-decrease", 0, 1, "0",
            "ours: stop once an iteration lowers the energy by less than this fraction "
            "(0: run all iterations)",
            [](const OptionValue& v, JobPlan& plan) { plan.vsa.min_relative_decrease = v.number; }),
        Choice("teleport", {"on", "off"}, "on",
               "region teleportation when the iterations stall (Cohen-Steiner et al. 2004)",
               [](const OptionValue& v, JobPlan& plan) { plan.vsa.teleport = v.text == "on"; }),
    };
    a.stages = {{"seed", "k initial clusters"},  // VSA has no growth option: CPU
                {"cluster", "Lloyd iterations: partition (flood), fit proxies"}};
    a.run_mesh = RunMeshVsa;
    algorithms.push_back(a);
  }

  // Points.
  const std::vector<std::string> point_energies = {"variance"};
  auto point_threads = ThreadsOption("the", SetPointThreads);
  {
    AlgorithmInfo a;
    a.name = "hc";
    a.wire = kWireHc;
    a.input = InputKind::kPoints;
    a.hierarchy = true;
    a.title = "hierarchical data clustering (Alg. 2.6)";
    a.help = "merges only, from the voxel-grid start (section 6.2) down to one cluster";
    a.energies = point_energies;
    a.options = {GridOption(kHierarchyGridHelp), PointStartOption(), point_threads,
                 DissertationPresetOption()};
    // HC's steps on the GPU with --device gpu (gpu/stages/points_multilevel_gpu.h).
    a.stages = {merge_stage};
    a.run_points = RunPointHierarchy;
    algorithms.push_back(a);
  }
  {
    AlgorithmInfo a;
    a.name = "ml";
    a.wire = kWireMl;
    a.input = InputKind::kPoints;
    a.hierarchy = true;
    a.title = "multilevel data clustering (section 6.3)";
    a.help = "merges with local neighbours as dual edges, LN k-means around each merge";
    a.energies = point_energies;
    a.options = {GridOption(kHierarchyGridHelp), PointStartOption(), point_threads,
                 PointOptimizerOption()};
    a.options.push_back(BoundedDriftOption());
    a.options.push_back(DissertationPresetOption());
    // ML's steps (LN k-means around each merge) on the GPU with --device gpu.
    a.stages = {merge_stage};
    a.run_points = RunPointHierarchy;
    algorithms.push_back(a);
  }
  {
    AlgorithmInfo a;
    a.name = "pml";
    a.wire = kWirePml;
    a.input = InputKind::kPoints;
    a.hierarchy = true;
    a.title = "parallel multilevel data clustering (Alg. 5.3 on points)";
    a.help = "collapse mutual optimal dual edges per level, then ML";
    a.energies = point_energies;
    a.options = {GridOption(kHierarchyGridHelp), PointStartOption(),   point_threads,
                 PointOptimizerOption(),         PmlUntilOption(true), PmlPairsOption()};
    a.options.push_back(BoundedDriftOption());
    a.options.push_back(DissertationPresetOption());
    // The voxel start and PML's levels on the GPU (gpu/stages/points_multilevel_gpu.h):
    // merges, with LN k-means inside the levels (--device gpu), without the switch to ML.
    a.stages = {merge_stage};
    a.run_points = RunPointHierarchy;
    algorithms.push_back(a);
  }
  auto point_init = [](std::vector<std::string> choices, std::string help) {
    return Choice("init", std::move(choices), "kmeans++", std::move(help),
                  [](const OptionValue& v, JobPlan& plan) {
                    plan.point_init = v.text == "random" ? JobPlan::PointInit::kRandom
                                      : v.text == "grid" ? JobPlan::PointInit::kGrid
                                                         : JobPlan::PointInit::kKmeansPlusPlus;
                  });
  };
  {
    AlgorithmInfo a;
    a.name = "lnkmeans";
    a.wire = kWireLnKmeans;
    a.input = InputKind::kPoints;
    a.title = "local neighbours k-means (Alg. 6.1)";
    a.help = "each point checked against at most 4d - 1 neighbouring clusters, in parallel";
    a.energies = point_energies;
    // Alg. 6.1 starts from the voxel grid (section 6.2).
    a.options = {Ours(point_init({"kmeans++", "random", "grid"},
                                 "start: greedy k-means++ centres, random points, or one cluster "
                                 "per occupied voxel (section 6.2; no K)"),
                      "grid"),
                 GridOption("voxels per dimension of init grid's start (0 = from m and d)"),
                 point_threads,
                 Integer("max-iterations", 1, 1000000, "300", "LN k-means iterations at most",
                         [](const OptionValue& v, JobPlan& plan) {
                           plan.ln_kmeans.max_iterations = static_cast<uint32_t>(v.integer);
                         }),
                 DissertationPresetOption()};
    // Assign and the initial neighbours on the GPU (gpu/kernels/ln_kmeans.h), from seeds.
    a.stages = {{"cluster", "seeding, then LN k-means iterations (assign on the GPU)"}};
    a.run_points = RunPointLnKmeans;
    algorithms.push_back(a);
  }
  {
    AlgorithmInfo a;
    a.name = "kmeans";
    a.wire = kWireKmeans;
    a.input = InputKind::kPoints;
    a.title = "k-means (Lloyd, Alg. 2.4)";
    a.help = "brute-force Lloyd iterations from k-means++ or random centres (baseline)";
    a.energies = point_energies;
    a.options = {
        // k randomly picked points (l. 352).
        Ours(point_init({"kmeans++", "random", "grid"},
                        "centres: greedy k-means++, k distinct random points, or the means of the "
                        "occupied voxels (section 6.2's start, no K: Fig. 6.11 compares LN "
                        "k-means and k-means from it)"),
             "random"),
        GridOption("voxels per dimension of init grid's start (0 = from m and d)"), point_threads,
        Integer("max-iterations", 1, 1000000, "300", "Lloyd iterations at most",
                [](const OptionValue& v, JobPlan& plan) {
                  plan.kmeans.max_iterations = static_cast<uint32_t>(v.integer);
                }),
        DissertationPresetOption()};
    // The assignment on the GPU (gpu/kernels/kmeans_assign.h).
    a.stages = {{"cluster", "seeding, then Lloyd iterations (assignment on the GPU)"}};
    a.run_points = RunPointKmeans;
    algorithms.push_back(a);
  }
  auto divisive_init = [](std::string default_text, std::string help,
                          void (*set)(JobPlan&, KmeansOptions::Init)) {
    return Choice("init", {"kmeans++", "random"}, std::move(default_text), std::move(help),
                  [set](const OptionValue& v, JobPlan& plan) {
                    set(plan, v.text == "random" ? KmeansOptions::Init::kRandom
                                                 : KmeansOptions::Init::kKmeansPlusPlus);
                  });
  };
  {
    AlgorithmInfo a;
    a.name = "xmeans";
    a.wire = kWireXmeans;
    a.input = InputKind::kPoints;
    a.chooses_k = true;
    a.title = "X-means (Alg. 2.5, Pelleg & Moore)";
    a.help =
        "k-means from --clusters = k_min, then every cluster split in two by 2-means where the "
        "BIC of the halves beats the cluster's, and k-means again, until no split is kept (after "
        "--lookahead forced rounds, ours) or k_max; the result is the round of largest BIC";
    a.energies = point_energies;
    a.options = {
        Integer("kmax", 0, UINT32_MAX, "0",
                "k_max of Alg. 2.5: no round goes beyond it (0 = the number of points)",
                [](const OptionValue& v, JobPlan& plan) {
                  plan.xmeans.max_clusters = static_cast<uint32_t>(v.integer);
                }),
        Integer("split-trials", 1, 1000, "1",
                "2-means runs per virtual split (Alg. 2.5 line 3); the halves of least energy are "
                "tested",
                [](const OptionValue& v, JobPlan& plan) {
                  plan.xmeans.split_trials = static_cast<uint32_t>(v.integer);
                }),
        Ours(Integer(
                 "lookahead", 0, 64, "2",
                 "ours: after a round that keeps no split, up to this many forced rounds in a row "
                 "split every cluster anyway (k doubles), so that the search passes the BIC's "
                 "local maximum at few clusters (from k_min = 1 Alg. 2.5 stops at one cluster "
                 "on blobs spread over a volume); 0 = Alg. 2.5's stop at the first round that "
                 "keeps no split",
                 [](const OptionValue& v, JobPlan& plan) {
                   plan.xmeans.lookahead = static_cast<uint32_t>(v.integer);
                 }),
             "0"),
        divisive_init("kmeans++", "seeding of the first k-means and of every 2-means",
                      [](JobPlan& plan, KmeansOptions::Init init) { plan.xmeans.init = init; }),
        point_threads,
        Integer("max-iterations", 1, 1000000, "300", "Lloyd iterations of every k-means run",
                [](const OptionValue& v, JobPlan& plan) {
                  plan.xmeans.max_iterations = static_cast<uint32_t>(v.integer);
                }),
        DissertationPresetOption()};
    a.stages = {{"seed", "k-means at k_min (Alg. 2.5 line 1)"},
                {"cluster", "rounds of virtual splits tested by the BIC, then k-means"}};
    a.run_points = RunPointXmeans;
    algorithms.push_back(a);
  }
  {
    AlgorithmInfo a;
    a.name = "bisecting";
    a.wire = kWireBisecting;
    a.input = InputKind::kPoints;
    a.hierarchy = true;
    a.divisive = true;
    a.title = "bisecting k-means (Alg. 2.7, Steinbach et al.)";
    a.help =
        "from one cluster, split a cluster in two by 2-means until there are --clusters K; the "
        "levels are K clusters, then the splits undone, down to one";
    a.energies = point_energies;
    a.options = {
        Texts(Choice("split", {"size", "energy"}, "size",
                     "the cluster split: the largest (Alg. 2.7's \"largest cluster\") or, ours to "
                     "offer (scikit-learn's default), the one of largest energy",
                     [](const OptionValue& v, JobPlan& plan) {
                       plan.bisecting.split =
                           v.text == "energy" ? BisectingKmeansOptions::SplitChoice::kLargestEnergy
                                              : BisectingKmeansOptions::SplitChoice::kLargestSize;
                     })),
        Integer("trials", 1, 1000, "1",
                "L of Alg. 2.7: 2-means runs per split (seeds S, S+1, ...), the split of least "
                "energy kept",
                [](const OptionValue& v, JobPlan& plan) {
                  plan.bisecting.trials = static_cast<uint32_t>(v.integer);
                }),
        divisive_init("random", "seeding of each 2-means: two random points or k-means++",
                      [](JobPlan& plan, KmeansOptions::Init init) { plan.bisecting.init = init; }),
        point_threads,
        Integer("max-iterations", 1, 1000000, "300", "Lloyd iterations of each 2-means run",
                [](const OptionValue& v, JobPlan& plan) {
                  plan.bisecting.max_iterations = static_cast<uint32_t>(v.integer);
                })};
    a.stages = {{"cluster", "splits by 2-means to K clusters"}};
    a.run_points = RunPointBisecting;
    algorithms.push_back(a);
  }
  for (AlgorithmInfo& algorithm : algorithms) DescribeDissertationPreset(algorithm);
  return algorithms;
}

const std::vector<OptionInfo>& EnergyOptionTable() {
  static const auto* table = new std::vector<OptionInfo>(BuildEnergyOptions());
  return *table;
}

const std::vector<AlgorithmInfo>& AlgorithmTable() {
  static const auto* table = new std::vector<AlgorithmInfo>(BuildAlgorithms());
  return *table;
}

std::string FormatNumber(const OptionInfo& option, double value) {
  return option.type == OptionInfo::Type::kInteger ? absl::StrCat(static_cast<int64_t>(value))
                                                   : absl::StrCat(value);
}

}  // namespace

const char* InputKindName(InputKind input) { return input == InputKind::kMesh ? "mesh" : "points"; }

absl::StatusOr<DeviceChoice> ParseDeviceChoice(absl::string_view name) {
  if (name.empty() || name == "auto") return DeviceChoice::kAuto;
  if (name == "gpu") return DeviceChoice::kGpu;
  if (name == "cpu") return DeviceChoice::kCpu;
  return absl::InvalidArgumentError(
      absl::StrCat("option device: '", name, "' is not one of auto, gpu, cpu"));
}

const char* OptionTypeName(OptionInfo::Type type) {
  switch (type) {
    case OptionInfo::Type::kChoice:
      return "choice";
    case OptionInfo::Type::kInteger:
      return "integer";
    case OptionInfo::Type::kNumber:
      return "number";
  }
  return "?";
}

absl::StatusOr<OptionValue> ParseOptionValue(const OptionInfo& option, absl::string_view text) {
  OptionValue value;
  value.text = std::string(text);
  switch (option.type) {
    case OptionInfo::Type::kChoice:
      if (std::find(option.choices.begin(), option.choices.end(), text) != option.choices.end()) {
        return value;
      }
      return absl::InvalidArgumentError(absl::StrCat("option ", option.name, ": '", text,
                                                     "' is not one of ",
                                                     absl::StrJoin(option.choices, ", ")));
    case OptionInfo::Type::kInteger:
      if (absl::SimpleAtoi(text, &value.integer) && value.integer >= option.low &&
          value.integer <= option.high) {
        return value;
      }
      return absl::InvalidArgumentError(absl::StrCat(
          "option ", option.name, ": '", text, "' is not an integer in [",
          FormatNumber(option, option.low), ", ", FormatNumber(option, option.high), "]"));
    case OptionInfo::Type::kNumber:
      if (absl::SimpleAtod(text, &value.number) && value.number >= option.low &&
          value.number <= option.high) {
        return value;
      }
      return absl::InvalidArgumentError(absl::StrCat("option ", option.name, ": '", text,
                                                     "' is not a number in [", option.low, ", ",
                                                     option.high, "]"));
  }
  return absl::InternalError("unknown option type");
}

std::string OptionDefaultNote(const OptionInfo& option) {
  switch (option.default_origin) {
    case OptionInfo::Origin::kUnmarked:
      return option.default_text;
    case OptionInfo::Origin::kText:
      return absl::StrCat(option.default_text, " (the text's)");
    case OptionInfo::Origin::kOurs:
      return absl::StrCat(option.default_text, " (ours; the text's: ",
                          option.text_variant.empty() ? "the user's value" : option.text_variant,
                          ", preset ", kDissertationPreset, ")");
  }
  return option.default_text;
}

namespace {

// The first entry of `table` for which `match` holds; nullptr if none.
template <typename Info, typename Match>
const Info* FindIn(std::span<const Info> table, Match&& match) {
  for (const Info& info : table) {
    if (match(info)) return &info;
  }
  return nullptr;
}

// The names of `table`'s entries for `input`, comma-separated, in table order.
template <typename Info>
std::string NamesFor(std::span<const Info> table, InputKind input) {
  std::vector<std::string> names;
  for (const Info& info : table) {
    if (info.input == input) names.push_back(info.name);
  }
  return absl::StrJoin(names, ", ");
}

}  // namespace

std::span<const EnergyInfo> Energies() { return EnergyTable(); }
std::span<const OptionInfo> EnergyOptions() { return EnergyOptionTable(); }

const EnergyInfo* FindEnergy(InputKind input, absl::string_view name) {
  return FindIn(Energies(),
                [&](const EnergyInfo& e) { return e.input == input && e.name == name; });
}

const EnergyInfo* FindEnergyByWire(InputKind input, int wire) {
  if (wire == 0) return nullptr;
  return FindIn(Energies(),
                [&](const EnergyInfo& e) { return e.input == input && e.wire == wire; });
}

const EnergyInfo* FindEnergyByKind(MeshEnergyKind kind) {
  return FindIn(Energies(), [&](const EnergyInfo& e) {
    return e.input == InputKind::kMesh && e.mesh_kind == kind;
  });
}

std::span<const AlgorithmInfo> Algorithms() { return AlgorithmTable(); }

const AlgorithmInfo* FindAlgorithm(InputKind input, absl::string_view name) {
  return FindIn(Algorithms(),
                [&](const AlgorithmInfo& a) { return a.input == input && a.name == name; });
}

const AlgorithmInfo* FindAlgorithmByWire(InputKind input, int wire) {
  if (wire == 0) return nullptr;
  return FindIn(Algorithms(),
                [&](const AlgorithmInfo& a) { return a.input == input && a.wire == wire; });
}

const AlgorithmInfo& DefaultAlgorithm(InputKind input) { return *FindAlgorithm(input, "ml"); }

std::string AlgorithmNames(InputKind input) { return NamesFor(Algorithms(), input); }

std::string EnergyNames(InputKind input) { return NamesFor(Energies(), input); }

std::vector<const OptionInfo*> AlgorithmOptions(const AlgorithmInfo& algorithm) {
  std::vector<const OptionInfo*> options;
  for (const OptionInfo& option : algorithm.options) options.push_back(&option);
  if (algorithm.input == InputKind::kMesh) {
    for (const OptionInfo& option : EnergyOptionTable()) options.push_back(&option);
  }
  return options;
}

const OptionInfo* FindOption(const AlgorithmInfo& algorithm, absl::string_view name) {
  for (const OptionInfo* option : AlgorithmOptions(algorithm)) {
    if (option->name == name) return option;
  }
  return nullptr;
}

absl::StatusOr<JobPlan> PlanJob(const JobRequest& request) {
  if (request.algorithm == nullptr) return absl::InvalidArgumentError("algorithm: none given");
  const AlgorithmInfo& algorithm = *request.algorithm;
  JobPlan plan;
  plan.algorithm = &algorithm;
  plan.clusters = request.clusters;
  plan.seed = request.seed;
  plan.device = request.device;

  // The energy: one the algorithm runs.
  const EnergyInfo* energy = request.energy != nullptr
                                 ? request.energy
                                 : FindEnergy(algorithm.input, algorithm.energies[0]);
  if (energy == nullptr || energy->input != algorithm.input ||
      std::find(algorithm.energies.begin(), algorithm.energies.end(), energy->name) ==
          algorithm.energies.end()) {
    return absl::InvalidArgumentError(
        absl::StrCat("energy: ", energy != nullptr ? energy->name : "?", " is not available for ",
                     algorithm.name, " on ", InputKindName(algorithm.input),
                     " (available: ", absl::StrJoin(algorithm.energies, ", "), ")"));
  }
  plan.energy = energy;
  plan.mesh_energy.kind = energy->mesh_kind;

  // Options: every name known to the algorithm, every value in range; applied in the
  // order the algorithm lists them, so the result does not depend on the request's order.
  std::set<std::string> seen;
  for (const auto& [name, text] : request.options) {
    if (FindOption(algorithm, name) == nullptr) {
      std::vector<std::string> known;
      for (const OptionInfo* option : AlgorithmOptions(algorithm)) known.push_back(option->name);
      return absl::InvalidArgumentError(
          absl::StrCat("option ", name, " is not known for ", algorithm.name,
                       " (available: ", absl::StrJoin(known, ", "), ")"));
    }
    if (!seen.insert(name).second) {
      return absl::InvalidArgumentError(absl::StrCat("option ", name, ": given twice"));
    }
  }
  // The preset dissertation: the text's variant of every option whose default is ours, before
  // the options given (so that those win).
  const bool dissertation =
      std::any_of(request.options.begin(), request.options.end(),
                  [](const std::pair<std::string, std::string>& option) {
                    return option.first == "preset" && option.second == kDissertationPreset;
                  });
  if (dissertation) {
    for (const OptionInfo* option : AlgorithmOptions(algorithm)) {
      if (option->default_origin != OptionInfo::Origin::kOurs || option->text_variant.empty() ||
          seen.contains(option->name)) {
        continue;
      }
      MLCLUST_ASSIGN_OR_RETURN(OptionValue value, ParseOptionValue(*option, option->text_variant));
      option->apply(value, plan);
    }
  }
  for (const OptionInfo* option : AlgorithmOptions(algorithm)) {
    for (const auto& [name, text] : request.options) {
      if (name != option->name) continue;
      MLCLUST_ASSIGN_OR_RETURN(OptionValue value, ParseOptionValue(*option, text));
      option->apply(value, plan);
    }
  }
  // The voxel grid's a is the user's in the text (section 6.2, l. 2605): no automatic grid,
  // not even given explicitly (0 is ours).
  const bool grid_start =
      algorithm.input == InputKind::kPoints && ((algorithm.hierarchy && !algorithm.divisive) ||
                                                plan.point_init == JobPlan::PointInit::kGrid);
  if (dissertation && grid_start && plan.grid == 0) {
    return absl::InvalidArgumentError(absl::StrCat(
        "option grid: preset dissertation starts ", algorithm.name,
        " from the voxel grid, whose voxels per dimension the text leaves to the user (section "
        "6.2; 0, the automatic grid, is ours): give grid >= 1"));
  }
  if (algorithm.input == InputKind::kMesh) {
    MLCLUST_RETURN_IF_ERROR(ValidateMeshEnergyOptions(plan.mesh_energy));
  }

  // Clusters and levels.
  if (algorithm.hierarchy) {
    if (request.levels_high != 0 && request.levels_high < request.levels_low) {
      return absl::InvalidArgumentError(absl::StrCat("levels: the high end ", request.levels_high,
                                                     " is below the low end ", request.levels_low));
    }
    if (algorithm.divisive) {
      // Its top is K; the levels go down to one cluster.
      if (request.clusters < 1) {
        return absl::InvalidArgumentError(absl::StrCat(
            "clusters: ", algorithm.name, " needs k >= 1 clusters (the top of its hierarchy)"));
      }
      plan.bisecting.clusters = request.clusters;
      plan.bisecting.seed = request.seed;
      return plan;
    }
    const uint32_t lowest = std::max<uint32_t>({1, request.clusters, request.levels_low});
    plan.multilevel.min_clusters = lowest;
    plan.point_multilevel.min_clusters = lowest;
    if (algorithm.name == "hc") {
      plan.multilevel.optimizer = MultilevelOptions::Optimizer::kNone;
      plan.point_multilevel.optimizer = PointMultilevelOptions::Optimizer::kNone;
    }
    if (algorithm.name == "pml") {
      plan.multilevel.parallel = true;
      plan.point_multilevel.parallel = true;
    }
  } else {
    if (request.levels_high != 0 || request.levels_low != 0) {
      return absl::InvalidArgumentError(
          "levels: a level range applies to the hierarchies (HC, ML, PML, bisecting) only");
    }
    if (plan.point_init == JobPlan::PointInit::kGrid) {
      if (request.clusters != 0) {
        return absl::InvalidArgumentError(absl::StrCat(
            "clusters: init grid starts from one cluster per occupied voxel (option grid); ",
            request.clusters, " clusters cannot be asked for with it"));
      }
    } else {
      if (request.clusters < 1) {
        return absl::InvalidArgumentError(
            absl::StrCat("clusters: ", algorithm.name, " needs k >= 1 clusters"));
      }
      if (plan.grid != 0 && algorithm.input == InputKind::kPoints) {
        return absl::InvalidArgumentError("grid: applies to init grid (and the hierarchies)");
      }
    }
    plan.seeds.clusters = request.clusters;
    plan.seeds.seed = request.seed;
    plan.vsa.clusters = request.clusters;
    plan.vsa.seed = request.seed;
    plan.kmeans.clusters = request.clusters;
    plan.kmeans.seed = request.seed;
    plan.xmeans.min_clusters = request.clusters;
    plan.xmeans.seed = request.seed;
    if (algorithm.chooses_k && plan.xmeans.max_clusters != 0 &&
        plan.xmeans.max_clusters < request.clusters) {
      return absl::InvalidArgumentError(absl::StrCat("option kmax: ", plan.xmeans.max_clusters,
                                                     " is below clusters (k_min) ",
                                                     request.clusters));
    }
  }
  return plan;
}

const char* PlanStageName(PlanStage stage) {
  switch (stage) {
    case PlanStage::kMeasures:
      return "measures";
    case PlanStage::kSeed:
      return "seed";
    case PlanStage::kCluster:
      return "cluster";
  }
  return "?";
}

std::optional<PlanStage> PlanStageFromName(absl::string_view name) {
  for (PlanStage stage : {PlanStage::kMeasures, PlanStage::kSeed, PlanStage::kCluster}) {
    if (name == PlanStageName(stage)) return stage;
  }
  return std::nullopt;
}

const StagePlan* FindStage(const JobPlan& plan, PlanStage stage) {
  for (const StagePlan& planned : plan.stages) {
    if (planned.stage == stage) return &planned;
  }
  return nullptr;
}

const StagePlan* FindStage(const JobPlan& plan, absl::string_view name) {
  const std::optional<PlanStage> stage = PlanStageFromName(name);
  return stage.has_value() ? FindStage(plan, *stage) : nullptr;
}

}  // namespace mlclust
