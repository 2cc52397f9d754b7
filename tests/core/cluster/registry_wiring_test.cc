// X-means and bisecting k-means as the registry runs them (the server and the CLI run them
// this way): the levels are the library's results.
#include <vector>

#include "core/base/status_macros.h"
#include "core/cluster/bisecting_kmeans.h"
#include "core/cluster/registry.h"
#include "core/cluster/xmeans.h"
#include "core/hierarchy/hierarchy.h"
#include "core/plan/device_policy.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "tests/fixtures/recording_sink.h"
#include "tests/fixtures/test_points.h"

namespace mlclust {
namespace {

using ::testing::HasSubstr;

using testing::LogSink;

absl::StatusOr<JobPlan> Plan(const char* algorithm, uint32_t clusters,
                             std::vector<std::pair<std::string, std::string>> options = {}) {
  JobRequest request;
  request.algorithm = FindAlgorithm(InputKind::kPoints, algorithm);
  request.clusters = clusters;
  request.seed = 7;
  request.options = std::move(options);
  absl::StatusOr<JobPlan> plan = PlanJob(request);
  if (plan.ok()) MLCLUST_RETURN_IF_ERROR(PlanDevices(DeviceCaps{}, *plan));
  return plan;
}

// Plan(algorithm, clusters, options) run on `points` into `sink` through the registry.
absl::StatusOr<RunSummary> PlanAndRun(const PointSet& points, const char* algorithm,
                                      uint32_t clusters,
                                      std::vector<std::pair<std::string, std::string>> options,
                                      LogSink& sink) {
  MLCLUST_ASSIGN_OR_RETURN(const JobPlan plan, Plan(algorithm, clusters, std::move(options)));
  return plan.algorithm->run_points(points, plan, sink, RunContext{});
}

TEST(RegistryWiringTest, XmeansLevelsAreItsFirstKmeansThenItsResult) {
  const testing::Blobs blobs = testing::GaussianBlobs(4, 50, 12, 3);
  LogSink sink;
  absl::StatusOr<RunSummary> summary =
      PlanAndRun(blobs.points, "xmeans", 1, {{"kmax", "10"}}, sink);
  ASSERT_TRUE(summary.ok()) << summary.status();
  XmeansOptions direct;
  direct.min_clusters = 1;
  direct.max_clusters = 10;
  direct.seed = 7;
  absl::StatusOr<XmeansResult> expected = RunXmeans(blobs.points, direct);
  ASSERT_TRUE(expected.ok()) << expected.status();
  ASSERT_EQ(sink.log.num_levels(), 2u);
  EXPECT_EQ(sink.log.cluster_count(0), 1u);
  EXPECT_DOUBLE_EQ(sink.log.energy(0), expected->rounds[0].inertia);  // Alg. 2.5 line 1
  EXPECT_EQ(sink.log.cluster_count(1), expected->clusters);
  EXPECT_EQ(expected->clusters, 4u);
  EXPECT_DOUBLE_EQ(sink.log.energy(1), expected->inertia);
  EXPECT_EQ(*sink.log.LabelsAt(1), expected->labels);
  EXPECT_EQ(summary->final_clusters, 4u);
}

TEST(RegistryWiringTest, XmeansStoppedAtKminMovesNothing) {
  const testing::Blobs blobs = testing::GaussianBlobs(4, 50, 12, 3);
  LogSink sink;
  ASSERT_TRUE(PlanAndRun(blobs.points, "xmeans", 3, {{"kmax", "3"}}, sink).ok());
  ASSERT_EQ(sink.log.num_levels(), 2u);
  EXPECT_EQ(sink.log.num_moves(), 0u);  // level 0 is exactly the round X-means kept
  EXPECT_EQ(sink.log.energy(0), sink.log.energy(1));
}

TEST(RegistryWiringTest, BisectingLevelsAreTheSplitsUndone) {
  const testing::Blobs blobs = testing::GaussianBlobs(5, 40, 10, 4);
  LogSink sink;
  absl::StatusOr<RunSummary> summary =
      PlanAndRun(blobs.points, "bisecting", 8, {{"split", "energy"}, {"trials", "3"}}, sink);
  ASSERT_TRUE(summary.ok()) << summary.status();
  BisectingKmeansOptions direct;
  direct.clusters = 8;
  direct.split = BisectingKmeansOptions::SplitChoice::kLargestEnergy;
  direct.trials = 3;
  direct.seed = 7;
  absl::StatusOr<BisectingKmeansResult> expected = RunBisectingKmeans(blobs.points, direct);
  ASSERT_TRUE(expected.ok()) << expected.status();
  ASSERT_EQ(sink.log.num_levels(), 8u);
  for (size_t l = 0; l < 8; ++l) EXPECT_EQ(sink.log.cluster_count(l), 8 - l);
  EXPECT_EQ(*sink.log.LabelsAt(0), expected->labels);
  EXPECT_DOUBLE_EQ(sink.log.energy(0), expected->inertia);
  // Level l (8 - l clusters) has the energy after split 7 - l; the last level, one cluster.
  for (size_t l = 1; l < 7; ++l) {
    EXPECT_DOUBLE_EQ(sink.log.energy(l), expected->splits[6 - l].energy) << l;
  }
  EXPECT_DOUBLE_EQ(sink.log.energy(7), expected->initial_energy);
  EXPECT_EQ(summary->start_clusters, 8u);
  EXPECT_EQ(summary->final_clusters, 1u);
}

TEST(RegistryWiringTest, PlansRefuseWhatTheDriversWouldRefuse) {
  EXPECT_THAT(std::string(Plan("bisecting", 0).status().message()), HasSubstr("clusters"));
  EXPECT_THAT(std::string(Plan("xmeans", 5, {{"kmax", "4"}}).status().message()),
              HasSubstr("kmax"));
  EXPECT_THAT(std::string(Plan("xmeans", 0).status().message()), HasSubstr("clusters"));
  // Bisecting is a hierarchy: a level range is accepted.
  JobRequest request;
  request.algorithm = FindAlgorithm(InputKind::kPoints, "bisecting");
  request.clusters = 10;
  request.levels_high = 8;
  request.levels_low = 2;
  EXPECT_TRUE(PlanJob(request).ok());
  EXPECT_TRUE(FindAlgorithm(InputKind::kPoints, "bisecting")->divisive);
  EXPECT_TRUE(FindAlgorithm(InputKind::kPoints, "xmeans")->chooses_k);
}

}  // namespace
}  // namespace mlclust
