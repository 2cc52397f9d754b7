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
// error as the only string).
std::vector<std::string> RunWith(const AlgorithmInfo& algorithm,
                                 std::vector<std::pair<std::string, std::string>> options,
                                 const EnergyInfo* energy = nullptr) {
  JobRequest request;
  request.algorithm = &algorithm;
  request.energy = energy;
  request.clusters = algorithm.hierarchy && !algorithm.divisive ? 0 : 5;
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

}  // namespace
}  // namespace mlclust
