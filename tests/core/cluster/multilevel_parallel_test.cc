// PML's parallel options (ours): parallel_optimisation with independent_moves, and the
// registry's "parallel-optimisation" option that sets them; the face-order rounds run in
// parallel steps.
#include <gtest/gtest.h>

#include <span>
#include <vector>

#include "core/cluster/detail/multilevel_engine.h"
#include "core/cluster/multilevel.h"
#include "core/cluster/registry.h"
#include "core/io/mesh_io.h"
#include "tests/fixtures/level_checks.h"
#include "tests/fixtures/recording_sink.h"
#include "tests/fixtures/test_meshes.h"

namespace mlclust {
namespace {

using Loaded = testing::LoadedMesh;

const Loaded& File(const std::string& name) { return testing::LoadDataFile(name); }

MultilevelOptions IndependentMoves() {
  MultilevelOptions options;
  options.parallel = true;
  options.pml_until = 2000;
  options.parallel_optimisation = true;
  options.independent_moves = true;
  return options;
}

TEST(MultilevelParallelTest, RegistryOptionSetsTheRoundsAndIndependentMoves) {
  JobRequest request;
  request.algorithm = FindAlgorithm(InputKind::kMesh, "pml");
  ASSERT_NE(request.algorithm, nullptr);
  absl::StatusOr<JobPlan> plan = PlanJob(request);
  ASSERT_TRUE(plan.ok()) << plan.status();
  EXPECT_FALSE(plan->multilevel.parallel_optimisation);  // off by default
  EXPECT_FALSE(plan->multilevel.independent_moves);
  request.options = {{"parallel-optimisation", "rounds"}};
  plan = PlanJob(request);
  ASSERT_TRUE(plan.ok()) << plan.status();
  EXPECT_TRUE(plan->multilevel.parallel_optimisation);
  EXPECT_FALSE(plan->multilevel.independent_moves);
  request.options = {{"parallel-optimisation", "independent"}};
  plan = PlanJob(request);
  ASSERT_TRUE(plan.ok()) << plan.status();
  EXPECT_TRUE(plan->multilevel.parallel_optimisation);
  EXPECT_TRUE(plan->multilevel.independent_moves);
  request.options = {{"parallel-optimisation", "sometimes"}};
  EXPECT_FALSE(PlanJob(request).ok());
  // ML has no PML levels: not its option.
  request.algorithm = FindAlgorithm(InputKind::kMesh, "ml");
  request.options = {{"parallel-optimisation", "rounds"}};
  EXPECT_FALSE(PlanJob(request).ok());
}

// The pml preset many-cores (ours): the option set BENCHMARKS.md measured, by name; it
// overrides the options it names, and PML hands over at the asked clusters or 1000.
TEST(MultilevelParallelTest, PresetManyCoresSetsItsOptions) {
  JobRequest request;
  request.algorithm = FindAlgorithm(InputKind::kMesh, "pml");
  ASSERT_NE(request.algorithm, nullptr);
  request.clusters = 200;
  request.options = {{"preset", "many-cores"}, {"p-percent", "10"}};
  absl::StatusOr<JobPlan> plan = PlanJob(request);
  ASSERT_TRUE(plan.ok()) << plan.status();
  EXPECT_TRUE(plan->multilevel.parallel);
  EXPECT_EQ(plan->multilevel.p_percent, 95);
  EXPECT_EQ(plan->multilevel.p_percent_rule, MultilevelOptions::PPercentRule::kHcFirst);
  EXPECT_EQ(plan->multilevel.pml_until, 1000u);
  EXPECT_EQ(plan->multilevel.optimise_below_at_least, 2000u);
  EXPECT_TRUE(plan->multilevel.parallel_optimisation);
  EXPECT_FALSE(plan->multilevel.independent_moves);
  request.clusters = 5000;
  plan = PlanJob(request);
  ASSERT_TRUE(plan.ok()) << plan.status();
  EXPECT_EQ(plan->multilevel.pml_until, 5000u);
  request.options = {{"preset", "none"}};
  plan = PlanJob(request);
  ASSERT_TRUE(plan.ok()) << plan.status();
  EXPECT_EQ(plan->multilevel.p_percent, 0);
  EXPECT_FALSE(plan->multilevel.parallel_optimisation);
}

// optimise_below_at_least: with p95 on fandisk (12,946 faces) p% alone would leave every
// merge down to 647 clusters unoptimised; optimised below 2000, the level at 1000 is
// below HC's energy there and the optimiser moved faces.
TEST(MultilevelParallelTest, OptimiseBelowAtLeastOptimisesSmallMeshes) {
  const Loaded& mesh = File("fandisk.off");
  const MeshProblem problem = mesh.problem();
  auto energy_at_1000 = [&](uint32_t at_least, uint64_t* moves) {
    MultilevelOptions options;
    options.parallel = true;
    options.pml_until = 1000;
    options.p_percent = 95;
    options.p_percent_rule = MultilevelOptions::PPercentRule::kHcFirst;
    options.parallel_optimisation = true;
    options.optimise_below_at_least = at_least;
    options.min_clusters = 1000;
    HierarchyLog sink;
    absl::StatusOr<MultilevelSummary> summary = RunMultilevel(problem, options, sink);
    EXPECT_TRUE(summary.ok()) << summary.status();
    *moves = summary.ok() ? summary->optimisation_moves : 0;
    return summary.ok() ? summary->final_energy : 0.0;
  };
  uint64_t moves_p_alone = 0, moves_at_least = 0;
  const double p_alone = energy_at_1000(0, &moves_p_alone);
  const double at_least = energy_at_1000(2000, &moves_at_least);
  EXPECT_EQ(moves_p_alone, 0u);
  EXPECT_GT(moves_at_least, 0u);
  EXPECT_LT(at_least, p_alone);
}

// Independent moves: the levels rebuild the engine's labels, their energies are those of
// the labels, PML then ML stays within 5% of ML at k = 1000 and 200, and the optimiser
// moved faces (so the rounds ran).
TEST(MultilevelParallelTest, IndependentMovesGiveValidLevelsCloseToMl) {
  testing::ExpectValidLevelsCloseToMl(IndependentMoves(),
                                      [](size_t level) { return level % 5 == 2; });
}

// The winners of a round apply together: still the same levels on 1, 2 and 3 threads, and
// not the levels of the face-order rounds (another rule, so a test that could fail).
TEST(MultilevelParallelTest, IndependentMovesDoNotDependOnTheThreadCount) {
  const Loaded& l = File("fandisk.off");
  MultilevelOptions options = IndependentMoves();
  options.pml_until = 500;
  testing::RecordingSink runs[3];
  for (int t = 0; t < 3; ++t) {
    options.threads = t + 1;
    ASSERT_TRUE(RunMultilevel(l.problem(), options, runs[t]).ok());
  }
  EXPECT_GT(runs[0].counts.size(), 10u);
  for (int t = 1; t < 3; ++t) {
    EXPECT_EQ(runs[0].counts, runs[t].counts);
    EXPECT_EQ(runs[0].energies, runs[t].energies);
    EXPECT_EQ(runs[0].moves, runs[t].moves);
  }
  options.independent_moves = false;
  testing::RecordingSink face_order;
  ASSERT_TRUE(RunMultilevel(l.problem(), options, face_order).ok());
  EXPECT_NE(face_order.moves, runs[0].moves);
}

// With the guard off the winners read only their edge neighbours' clusters: still valid
// labels and energies.
TEST(MultilevelParallelTest, IndependentMovesWithoutGuardKeepEnergiesOfTheLabels) {
  const Loaded& l = File("fandisk.off");
  const MeshProblem problem = l.problem();
  MultilevelOptions options = IndependentMoves();
  options.connectivity_guard = false;
  options.guard = ConnectivityGuardKind::kOff;
  HierarchyLog pml;
  testing::ExpectMultilevelRebuildsEngineLabels(
      l, problem, options, [](size_t level) { return level % 9 == 4; }, pml);
}

// The face-order rounds (parallel_optimisation without independent moves) run in parallel
// steps where a round has enough candidates: every level (counts, energy bits, triplets in
// order) is the one the loop in list order gives, on 1, 2 and 3 threads, with the ring guard
// and without a guard, for PML to 500 and for the preset many-cores' options; and the steps
// ran (their round counter grew).
TEST(MultilevelParallelTest, FaceOrderRoundsInStepsGiveTheLoopsLevels) {
  const Loaded& l = File("fandisk.off");
  struct StepsOn {
    ~StepsOn() { detail::face_order_steps = detail::FaceOrderSteps::kFromFourThreads; }
  } steps_on;
  MultilevelOptions pml;
  pml.parallel = true;
  pml.pml_until = 500;
  pml.parallel_optimisation = true;
  MultilevelOptions unguarded = pml;
  unguarded.connectivity_guard = false;
  unguarded.guard = ConnectivityGuardKind::kOff;
  MultilevelOptions preset = pml;  // the registry's many-cores
  preset.pml_until = 1000;
  preset.p_percent = 95;
  preset.p_percent_rule = MultilevelOptions::PPercentRule::kHcFirst;
  preset.optimise_below_at_least = 2000;
  for (MultilevelOptions options : {pml, unguarded, preset}) {
    options.threads = 1;
    detail::face_order_steps = detail::FaceOrderSteps::kNever;
    testing::RecordingSink loop;
    ASSERT_TRUE(RunMultilevel(l.problem(), options, loop).ok());
    detail::face_order_steps = detail::FaceOrderSteps::kAlways;
    EXPECT_GT(loop.counts.size(), 10u);
    for (int t = 1; t <= 3; ++t) {
      options.threads = t;
      const uint64_t rounds = detail::face_order_steps_counters.rounds.load();
      testing::RecordingSink steps;
      ASSERT_TRUE(RunMultilevel(l.problem(), options, steps).ok());
      EXPECT_GT(detail::face_order_steps_counters.rounds.load(), rounds);
      EXPECT_EQ(loop.counts, steps.counts) << t << " threads";
      EXPECT_EQ(loop.energies, steps.energies) << t << " threads";
      EXPECT_EQ(loop.moves, steps.moves) << t << " threads";
    }
  }
}

}  // namespace
}  // namespace mlclust
