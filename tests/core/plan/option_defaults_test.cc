// Every option's help default (OptionInfo::default_text, what `mlclust help` prints) is its
// options struct's default: giving the default explicitly plans and runs exactly as not
// giving the option, for every algorithm and every option it accepts.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "core/cluster/registry.h"
#include "core/plan/device_policy.h"
#include "tests/fixtures/recording_sink.h"
#include "tests/fixtures/test_meshes.h"
#include "tests/fixtures/test_points.h"

namespace mlclust {
namespace {

// The whole hierarchy of a run of `algorithm` with `options` (a failed plan or run: the
// error as the only string); `clusters` < 0: 0 for the agglomerative hierarchies, 5 otherwise.
std::vector<std::string> RunWith(const AlgorithmInfo& algorithm,
                                 std::vector<std::pair<std::string, std::string>> options,
                                 const EnergyInfo* energy = nullptr, int clusters = -1) {
  JobRequest request;
  request.algorithm = &algorithm;
  request.energy = energy;
  request.clusters = clusters >= 0                                ? static_cast<uint32_t>(clusters)
                     : algorithm.hierarchy && !algorithm.divisive ? 0
                                                                  : 5;
  request.seed = 3;
  request.options = std::move(options);
  absl::StatusOr<JobPlan> plan = PlanJob(request);
  if (!plan.ok()) return {plan.status().ToString()};
  if (absl::Status s = PlanDevices(DeviceCaps(), *plan); !s.ok()) return {s.ToString()};
  testing::LogSink sink;
  absl::StatusOr<RunSummary> summary;
  if (algorithm.input == InputKind::kMesh) {
    static const testing::LoadedMesh* cube =
        new testing::LoadedMesh(testing::Load(testing::MakeCube(3).mesh));
    const MeshProblem problem{&cube->mesh, &cube->adjacency, &cube->measures, plan->mesh_energy};
    summary = algorithm.run_mesh(problem, *plan, sink, RunContext());
  } else {
    static const testing::Blobs* blobs = new testing::Blobs(testing::GaussianBlobs(5, 30, 10, 7));
    summary = algorithm.run_points(blobs->points, *plan, sink, RunContext());
  }
  if (!summary.ok()) return {summary.status().ToString()};
  std::vector<std::string> levels;
  for (size_t level = 0; level < sink.log.num_levels(); ++level) {
    const absl::StatusOr<std::vector<ClusterId>> at = sink.log.LabelsAt(level);
    if (!at.ok()) return {at.status().ToString()};
    std::string labels;
    for (ClusterId label : *at) absl::StrAppend(&labels, label.value(), ",");
    levels.push_back(
        absl::StrCat(sink.log.cluster_count(level), " ", sink.log.energy(level), " ", labels));
  }
  return levels;
}

TEST(OptionDefaultsTest, EveryAlgorithmOptionsHelpDefaultIsTheStructsDefault) {
  int checked = 0;
  for (const AlgorithmInfo& algorithm : Algorithms()) {
    const std::vector<std::string> plain = RunWith(algorithm, {});
    ASSERT_GT(plain.size(), 1u) << algorithm.name << ": " << plain[0];
    for (const OptionInfo& option : algorithm.options) {
      const std::string what = absl::StrCat(InputKindName(algorithm.input), " ", algorithm.name,
                                            " --", option.name, " ", option.default_text);
      ASSERT_TRUE(ParseOptionValue(option, option.default_text).ok()) << what;
      EXPECT_EQ(RunWith(algorithm, {{option.name, option.default_text}}), plain) << what;
      ++checked;
    }
  }
  EXPECT_GT(checked, 50);
}

// The energy options, on ML. A default that depends on the energy reads "VALUE for NAMES,
// VALUE for NAMES" (NAMES: energies joined by " and ", "mwcvd-*" for the three MWCVDs):
// each VALUE is checked with each energy it names.
TEST(OptionDefaultsTest, EveryEnergyOptionsHelpDefaultIsTheStructsDefault) {
  const AlgorithmInfo& ml = *FindAlgorithm(InputKind::kMesh, "ml");
  int checked = 0;
  for (const OptionInfo& option : EnergyOptions()) {
    if (ParseOptionValue(option, option.default_text).ok()) {
      EXPECT_EQ(RunWith(ml, {{option.name, option.default_text}}), RunWith(ml, {})) << option.name;
      ++checked;
      continue;
    }
    for (absl::string_view part : absl::StrSplit(option.default_text, ", ")) {
      const std::vector<std::string> value_names = absl::StrSplit(part, " for ");
      ASSERT_EQ(value_names.size(), 2u) << option.name << ": '" << part << "'";
      ASSERT_TRUE(ParseOptionValue(option, value_names[0]).ok()) << option.name << ": " << part;
      for (absl::string_view name : absl::StrSplit(value_names[1], " and ")) {
        int energies = 0;
        for (const EnergyInfo& energy : Energies()) {
          const bool named = absl::EndsWith(name, "*")
                                 ? absl::StartsWith(energy.name, name.substr(0, name.size() - 1))
                                 : energy.name == name;
          if (!named || energy.input != InputKind::kMesh) continue;
          EXPECT_EQ(RunWith(ml, {{option.name, value_names[0]}}, &energy), RunWith(ml, {}, &energy))
              << option.name << " " << value_names[0] << " for " << energy.name;
          ++energies;
          ++checked;
        }
        EXPECT_GT(energies, 0) << option.name << ": no energy is named '" << name << "'";
      }
    }
  }
  EXPECT_GT(checked, 5);
}

// Whether `algorithm` offers the preset dissertation.
bool OffersDissertation(const AlgorithmInfo& algorithm) {
  const OptionInfo* preset = FindOption(algorithm, "preset");
  return preset != nullptr && ParseOptionValue(*preset, kDissertationPreset).ok();
}

// The preset dissertation runs exactly as every option whose default is ours given at the
// text's variant, for every algorithm that offers it (the grid, the user's in the text, given
// on both sides where the voxel start runs).
TEST(OptionDefaultsTest, PresetDissertationIsEveryTextVariantGiven) {
  int checked = 0;
  for (const AlgorithmInfo& algorithm : Algorithms()) {
    if (!OffersDissertation(algorithm)) continue;
    std::vector<std::pair<std::string, std::string>> variants;
    bool grid_start = algorithm.input == InputKind::kPoints && algorithm.hierarchy;
    for (const OptionInfo* option : AlgorithmOptions(algorithm)) {
      if (option->default_origin != OptionInfo::Origin::kOurs || option->text_variant.empty()) {
        continue;
      }
      variants.emplace_back(option->name, option->text_variant);
      if (option->name == "init" && option->text_variant == "grid") grid_start = true;
    }
    const std::string what = absl::StrCat(InputKindName(algorithm.input), " ", algorithm.name);
    ASSERT_FALSE(variants.empty()) << what;
    std::vector<std::pair<std::string, std::string>> preset = {{"preset", kDissertationPreset}};
    if (grid_start) {
      variants.emplace_back("grid", "3");
      preset.emplace_back("grid", "3");
    }
    const int clusters = grid_start && !algorithm.hierarchy ? 0 : -1;
    const std::vector<std::string> text = RunWith(algorithm, variants, nullptr, clusters);
    ASSERT_GT(text.size(), 1u) << what << ": " << text[0];
    EXPECT_EQ(RunWith(algorithm, preset, nullptr, clusters), text) << what;
    ++checked;
  }
  // ML, PML, EMLO and BB on meshes; HC, ML, PML, LN k-means, k-means and X-means on points.
  EXPECT_EQ(checked, 10);
}

// The plan of the preset holds the text's variants; an option given explicitly wins.
TEST(OptionDefaultsTest, PresetDissertationSetsTheTextsVariantsAndGivenOptionsWin) {
  JobRequest request;
  request.algorithm = FindAlgorithm(InputKind::kMesh, "emlo");
  request.clusters = 4;
  request.options = {{"preset", kDissertationPreset}};
  absl::StatusOr<JobPlan> plan = PlanJob(request);
  ASSERT_TRUE(plan.ok()) << plan.status();
  EXPECT_EQ(plan->seeds.growth, SeedOptions::Growth::kEnergyFree);
  EXPECT_EQ(plan->seeds.reduction, SeedOptions::Reduction::kReseedAndRegrow);
  EXPECT_EQ(plan->emlo.guard, ConnectivityGuardKind::kVertexBoundaryEdgeCount);

  request.options = {{"growth", "flood"}, {"preset", kDissertationPreset}, {"guard", "off"}};
  plan = PlanJob(request);
  ASSERT_TRUE(plan.ok()) << plan.status();
  EXPECT_EQ(plan->seeds.growth, SeedOptions::Growth::kEnergyOrdered);
  EXPECT_EQ(plan->seeds.reduction, SeedOptions::Reduction::kReseedAndRegrow);
  EXPECT_FALSE(plan->emlo.connectivity_guard);

  request.algorithm = FindAlgorithm(InputKind::kMesh, "pml");
  request.clusters = 0;
  request.options = {{"preset", kDissertationPreset}};
  plan = PlanJob(request);
  ASSERT_TRUE(plan.ok()) << plan.status();
  EXPECT_EQ(plan->multilevel.pml_pairs, PmlPairRule::kAll);
  request.options.emplace_back("pml-pairs", "cheaper-half");
  plan = PlanJob(request);
  ASSERT_TRUE(plan.ok()) << plan.status();
  EXPECT_EQ(plan->multilevel.pml_pairs, PmlPairRule::kCheaperHalf);

  request.algorithm = FindAlgorithm(InputKind::kPoints, "kmeans");
  request.clusters = 3;
  request.options = {{"preset", kDissertationPreset}};
  plan = PlanJob(request);
  ASSERT_TRUE(plan.ok()) << plan.status();
  EXPECT_EQ(plan->point_init, JobPlan::PointInit::kRandom);

  request.algorithm = FindAlgorithm(InputKind::kPoints, "ml");
  request.clusters = 0;
  request.options = {{"preset", kDissertationPreset}, {"grid", "4"}};
  plan = PlanJob(request);
  ASSERT_TRUE(plan.ok()) << plan.status();
  EXPECT_EQ(plan->point_multilevel.start, PointMultilevelOptions::Start::kOptimisedGrid);
  EXPECT_EQ(plan->point_multilevel.grid, 4u);
}

// The text leaves the voxel grid's a to the user: the preset needs it given where the voxel
// start runs, and not elsewhere.
TEST(OptionDefaultsTest, PresetDissertationNeedsTheGridWhereTheVoxelStartRuns) {
  JobRequest request;
  request.algorithm = FindAlgorithm(InputKind::kPoints, "pml");
  request.options = {{"preset", kDissertationPreset}};
  absl::StatusOr<JobPlan> plan = PlanJob(request);
  ASSERT_FALSE(plan.ok());
  EXPECT_EQ(plan.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE(absl::StrContains(plan.status().message(), "option grid: preset dissertation"))
      << plan.status();
  request.options.emplace_back("grid", "0");  // the automatic grid, ours: refused too
  EXPECT_FALSE(PlanJob(request).ok());
  request.options.back().second = "2";
  EXPECT_TRUE(PlanJob(request).ok());
  request.algorithm = FindAlgorithm(InputKind::kPoints, "lnkmeans");
  request.options = {{"preset", kDissertationPreset}};
  EXPECT_FALSE(PlanJob(request).ok());
  request.options.emplace_back("init", "kmeans++");
  request.clusters = 3;
  EXPECT_TRUE(PlanJob(request).ok());
}

// `mlclust help` marks each default it knows as the text's or ours, and the preset's help
// lists what it sets.
TEST(OptionDefaultsTest, HelpMarksTheDefaultsAsTheTextsOrOurs) {
  const AlgorithmInfo& emlo = *FindAlgorithm(InputKind::kMesh, "emlo");
  EXPECT_EQ(OptionDefaultNote(*FindOption(emlo, "growth")),
            "flood (ours; the text's: free, preset dissertation)");
  EXPECT_EQ(OptionDefaultNote(*FindOption(emlo, "seed-reduction")),
            "merge (ours; the text's: reseed, preset dissertation)");
  EXPECT_EQ(OptionDefaultNote(*FindOption(emlo, "init")), "lneigh (the text's)");
  EXPECT_EQ(OptionDefaultNote(*FindOption(emlo, "level")), "0");
  EXPECT_EQ(OptionDefaultNote(*FindOption(*FindAlgorithm(InputKind::kMesh, "pml"), "pml-pairs")),
            "cheaper-half (ours; the text's: all, preset dissertation)");
  const AlgorithmInfo& points_ml = *FindAlgorithm(InputKind::kPoints, "ml");
  EXPECT_EQ(OptionDefaultNote(*FindOption(points_ml, "grid")),
            "0 (ours; the text's: the user's value, preset dissertation)");
  EXPECT_EQ(OptionDefaultNote(*FindOption(points_ml, "start")),
            "grid (ours; the text's: optimised-grid, preset dissertation)");
  EXPECT_EQ(OptionDefaultNote(*FindOption(*FindAlgorithm(InputKind::kPoints, "kmeans"), "init")),
            "kmeans++ (ours; the text's: random, preset dissertation)");
  EXPECT_EQ(
      OptionDefaultNote(*FindOption(*FindAlgorithm(InputKind::kPoints, "bisecting"), "split")),
      "size (the text's)");
  EXPECT_TRUE(absl::StrContains(FindOption(emlo, "preset")->help,
                                "growth free, seed-reduction reseed, guard vertex-count; an "
                                "option given explicitly wins"))
      << FindOption(emlo, "preset")->help;
  // Every algorithm with a default of ours offers the preset.
  for (const AlgorithmInfo& algorithm : Algorithms()) {
    for (const OptionInfo* option : AlgorithmOptions(algorithm)) {
      if (option->default_origin != OptionInfo::Origin::kOurs) continue;
      EXPECT_TRUE(OffersDissertation(algorithm)) << algorithm.name << " --" << option->name;
    }
  }
}

}  // namespace
}  // namespace mlclust
