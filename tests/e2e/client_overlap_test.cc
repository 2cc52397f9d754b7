// The client rebuilds while the stream arrives (issue 13): a reader thread with a bounded
// queue gives the same hierarchy as one thread, and the labels it follows level by level
// for --clusters K (RunOptions::labels_for_clusters) are those of the level the CLI
// chooses (the last with exactly K clusters, else the first with fewer), replayed or not.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "client/client.h"
#include "core/io/draco_codec.h"
#include "server/server.h"
#include "tests/fixtures/test_meshes.h"
#include "tests/fixtures/test_server.h"

namespace mlclust {
namespace {

class ClientOverlapTest : public ::testing::Test {
 protected:
  void SetUp() override {
    server::ServerOptions options;
    options.gpu = server::GpuMode::kOff;
    server_ = testing::StartServer(options);
    ASSERT_TRUE(server_);
    channel_ = testing::ChannelTo(*server_);
    grid_ = *EncodeMeshToDraco(testing::Grid(30));  // 1,800 faces
  }

  absl::StatusOr<client::JobResult> Run(v1::Algorithm algorithm, uint32_t spec_clusters,
                                        uint32_t follow, size_t read_ahead) {
    v1::JobSpec spec;
    spec.set_input_kind(v1::INPUT_KIND_DRACO_MESH);
    spec.set_algorithm(algorithm);
    spec.set_energy(v1::ENERGY_CVD);
    spec.set_clusters(spec_clusters);
    client::RunOptions options;
    options.labels_for_clusters = follow;
    options.read_ahead_events = read_ahead;
    options.chunk_bytes = 4096;
    return client::RunJob(channel_, spec, grid_, options);
  }

  // The CLI's ChooseLevel (client/main.cc).
  static std::optional<size_t> Choose(const HierarchyLog& log, uint32_t k) {
    std::optional<size_t> level = log.LastLevelWith(k);
    return level.has_value() ? level : log.FirstLevelWithAtMost(k);
  }

  std::unique_ptr<server::Server> server_;
  std::shared_ptr<grpc::Channel> channel_;
  std::string grid_;
};

TEST_F(ClientOverlapTest, AReaderThreadGivesTheSameHierarchyAsOneThread) {
  absl::StatusOr<client::JobResult> one = Run(v1::ALGORITHM_ML, 0, 0, 0);
  absl::StatusOr<client::JobResult> ahead = Run(v1::ALGORITHM_ML, 0, 0, 2);  // a short queue
  ASSERT_TRUE(one.ok()) << one.status();
  ASSERT_TRUE(ahead.ok()) << ahead.status();
  ASSERT_EQ(one->hierarchy.num_levels(), 1800u);
  ASSERT_EQ(ahead->hierarchy.num_levels(), one->hierarchy.num_levels());
  EXPECT_EQ(ahead->hierarchy.num_moves(), one->hierarchy.num_moves());
  for (size_t level : {size_t{0}, size_t{900}, size_t{1799}}) {
    EXPECT_EQ(*ahead->hierarchy.LabelsAt(level), *one->hierarchy.LabelsAt(level));
    EXPECT_EQ(ahead->hierarchy.energy(level), one->hierarchy.energy(level));
  }
  EXPECT_FALSE(one->chosen_level.has_value());  // none asked
  EXPECT_TRUE(one->chosen_labels.empty());
}

TEST_F(ClientOverlapTest, TheFollowedLabelsAreThoseOfTheLevelTheCliChooses) {
  struct Case {
    v1::Algorithm algorithm;
    uint32_t spec_clusters;  // single-level algorithms: K
    uint32_t k;
  };
  // ML: every count once; PML: counts skipped (the first level with fewer); BB: the
  // seeding and the result at the same K (the last); K past the start: level 0.
  for (const Case& c :
       {Case{v1::ALGORITHM_ML, 0, 50}, Case{v1::ALGORITHM_ML, 0, 1}, Case{v1::ALGORITHM_PML, 0, 37},
        Case{v1::ALGORITHM_PML, 0, 500}, Case{v1::ALGORITHM_BB, 40, 40},
        Case{v1::ALGORITHM_ML, 0, 1800}, Case{v1::ALGORITHM_BB, 40, 2000}}) {
    SCOPED_TRACE(absl::StrCat("algorithm ", c.algorithm, ", k ", c.k));
    absl::StatusOr<client::JobResult> result = Run(c.algorithm, c.spec_clusters, c.k, 16);
    ASSERT_TRUE(result.ok()) << result.status();
    const std::optional<size_t> level = Choose(result->hierarchy, c.k);
    ASSERT_TRUE(level.has_value());
    ASSERT_EQ(result->chosen_level, level);
    EXPECT_EQ(result->chosen_labels, *result->hierarchy.LabelsAt(*level));
  }
  // PML skips counts: at least one of the asked ones had no exact level.
  absl::StatusOr<client::JobResult> pml = Run(v1::ALGORITHM_PML, 0, 0, 16);
  ASSERT_TRUE(pml.ok());
  EXPECT_LT(pml->hierarchy.num_levels(), 1800u);
  // A K below every level's count: nothing followed.
  absl::StatusOr<client::JobResult> bb = Run(v1::ALGORITHM_BB, 40, 10, 16);
  ASSERT_TRUE(bb.ok());
  EXPECT_FALSE(Choose(bb->hierarchy, 10).has_value());
  EXPECT_FALSE(bb->chosen_level.has_value());
}

}  // namespace
}  // namespace mlclust
