#include "core/hierarchy/hierarchy.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "tests/fixtures/labels.h"

namespace mlclust {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;

using testing::RawLabels;

absl::Status AddLevel(HierarchyLog& log, uint32_t count, double energy,
                      std::vector<uint32_t> element, std::vector<uint32_t> to,
                      std::vector<uint32_t> from) {
  return log.OnLevel({0, count, energy, element, to, from});
}

// Fig. 4.4's situation: a face leaves a cluster it joined in an earlier merge (the
// clustering is not nested), and both directions still rebuild every level.
TEST(HierarchyLogTest, NonNestedMovesRebuildForwardsAndBackwards) {
  HierarchyLog log;
  const std::vector<ClusterId> start = {ClusterId(0), ClusterId(1), ClusterId(2), ClusterId(3)};
  ASSERT_TRUE(log.OnStart(start, 4, 0.0).ok());
  ASSERT_TRUE(AddLevel(log, 3, 1.0, {1}, {0}, {1}).ok());  // {0,1} {2} {3}
  ASSERT_TRUE(AddLevel(log, 2, 2.0, {3}, {2}, {3}).ok());  // {0,1} {2,3}
  ASSERT_TRUE(
      AddLevel(log, 2, 1.5, {1, 2}, {2, 0}, {0, 2}).ok());  // 1 leaves, 2 joins: {0,2} {1,3}
  ASSERT_EQ(log.num_levels(), 4u);
  EXPECT_EQ(log.num_moves(), 4u);

  EXPECT_THAT(RawLabels(*log.LabelsAt(3)), ElementsAre(0, 2, 0, 2));
  std::vector<ClusterId> labels = *log.LabelsAt(3);
  ASSERT_TRUE(log.StepLabels(labels, 3, 1).ok());
  EXPECT_THAT(RawLabels(labels), ElementsAre(0, 0, 2, 3));
  ASSERT_TRUE(log.StepLabels(labels, 1, 2).ok());
  EXPECT_THAT(RawLabels(labels), ElementsAre(0, 0, 2, 2));
  ASSERT_TRUE(log.StepLabels(labels, 2, 0).ok());
  EXPECT_THAT(RawLabels(labels), ElementsAre(0, 1, 2, 3));
  EXPECT_EQ(log.cluster_count(2), 2u);
  EXPECT_DOUBLE_EQ(log.energy(3), 1.5);
  EXPECT_EQ(log.FirstLevelWithAtMost(3), 1u);
  EXPECT_EQ(log.FirstLevelWithAtMost(1), std::nullopt);
  EXPECT_EQ(log.LastLevelWith(2), 3u);  // levels 2 and 3 both have two clusters
  EXPECT_EQ(log.LastLevelWith(1), std::nullopt);
}

TEST(HierarchyLogTest, StepFromTheWrongLevelIsDataLoss) {
  HierarchyLog log;
  ASSERT_TRUE(log.OnStart(std::vector<ClusterId>{ClusterId(0), ClusterId(1)}, 2, 0).ok());
  ASSERT_TRUE(AddLevel(log, 1, 1, {1}, {0}, {1}).ok());
  std::vector<ClusterId> labels = {ClusterId(0), ClusterId(1)};  // level 0
  absl::Status status = log.StepLabels(labels, 1, 0);            // claims level 1
  EXPECT_EQ(status.code(), absl::StatusCode::kDataLoss);
  EXPECT_EQ(log.StepLabels(labels, 0, 5).code(), absl::StatusCode::kOutOfRange);
}

TEST(HierarchyLogTest, RejectsMalformedLevels) {
  HierarchyLog log;
  EXPECT_EQ(AddLevel(log, 1, 0, {}, {}, {}).code(), absl::StatusCode::kFailedPrecondition);
  ASSERT_TRUE(log.OnStart(std::vector<ClusterId>(3, ClusterId(0)), 1, 0).ok());
  absl::Status twice = AddLevel(log, 2, 0, {1, 1}, {1, 2}, {0, 0});
  EXPECT_EQ(twice.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(twice.message(), HasSubstr("element 1 appears twice"));
  EXPECT_THAT(AddLevel(log, 2, 0, {9}, {1}, {0}).message(), HasSubstr("element 9 out of range"));
  EXPECT_THAT(AddLevel(log, 2, 0, {1}, {1, 2}, {0}).message(), HasSubstr("differ in length"));
  // A failed level leaves the log unchanged; the same element may appear in later levels.
  EXPECT_EQ(log.num_levels(), 1u);
  EXPECT_TRUE(AddLevel(log, 2, 0, {1}, {1}, {0}).ok());
  EXPECT_TRUE(AddLevel(log, 3, 0, {1, 2}, {0, 2}, {1, 0}).ok());
}

}  // namespace
}  // namespace mlclust
