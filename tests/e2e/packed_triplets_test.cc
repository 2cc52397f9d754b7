// JobSpec.packed_triplets (issue 13): the same jobs over loopback gRPC with the repeated
// (varint) triplets and with the packed uint32 fields give the same hierarchy, level by
// level; packed batches carry only the packed fields, and a level bigger than a batch
// continues in the next one.
#include <gtest/gtest.h>

#include "client/client.h"
#include "core/io/draco_codec.h"
#include "mlclust/v1/mlclust.grpc.pb.h"
#include "server/server.h"
#include "tests/fixtures/test_meshes.h"
#include "tests/fixtures/test_server.h"

namespace mlclust {
namespace {

struct Seen {
  int batches = 0;
  int packed_batches = 0;     // with only the packed fields set
  int repeated_batches = 0;   // with only the repeated fields set
  int continued_batches = 0;  // last_level_continues
};

absl::StatusOr<client::JobResult> RunWith(const std::shared_ptr<grpc::Channel>& channel,
                                          v1::Algorithm algorithm, uint32_t clusters,
                                          uint32_t batch_triplets, bool packed,
                                          const std::string& bytes, Seen& seen) {
  v1::JobSpec spec;
  spec.set_input_kind(v1::INPUT_KIND_DRACO_MESH);
  spec.set_algorithm(algorithm);
  spec.set_energy(v1::ENERGY_CVD);
  spec.set_clusters(clusters);
  spec.set_batch_triplets(batch_triplets);
  client::RunOptions options;
  options.packed_triplets = packed;
  options.on_event = [&seen](const v1::JobEvent& event) {
    if (!event.has_levels()) return;
    const v1::LevelBatch& batch = event.levels();
    ++seen.batches;
    const bool has_packed = !batch.packed_element().empty();
    const bool has_repeated = batch.element_size() > 0;
    if (has_packed && !has_repeated) ++seen.packed_batches;
    if (has_repeated && !has_packed) ++seen.repeated_batches;
    if (batch.last_level_continues()) ++seen.continued_batches;
  };
  return client::RunJob(channel, spec, bytes, options);
}

// Every level of `a` and `b` alike: counts, energies, moves and labels.
void ExpectSameHierarchy(const HierarchyLog& a, const HierarchyLog& b) {
  ASSERT_EQ(a.num_elements(), b.num_elements());
  ASSERT_EQ(a.num_levels(), b.num_levels());
  ASSERT_EQ(a.num_moves(), b.num_moves());
  std::vector<ClusterId> labels_a(a.start_labels().begin(), a.start_labels().end());
  std::vector<ClusterId> labels_b(b.start_labels().begin(), b.start_labels().end());
  ASSERT_EQ(labels_a, labels_b);
  for (size_t level = 1; level < a.num_levels(); ++level) {
    ASSERT_EQ(a.cluster_count(level), b.cluster_count(level)) << "level " << level;
    ASSERT_EQ(a.energy(level), b.energy(level)) << "level " << level;
    const LevelMoves ma = a.level(level), mb = b.level(level);
    ASSERT_TRUE(
        std::equal(ma.element.begin(), ma.element.end(), mb.element.begin(), mb.element.end()))
        << "level " << level;
    ASSERT_TRUE(std::equal(ma.to_cluster.begin(), ma.to_cluster.end(), mb.to_cluster.begin(),
                           mb.to_cluster.end()))
        << "level " << level;
    ASSERT_TRUE(a.StepLabels(labels_a, level - 1, level).ok());
    ASSERT_TRUE(b.StepLabels(labels_b, level - 1, level).ok());
    ASSERT_EQ(labels_a, labels_b) << "level " << level;
  }
}

class PackedTripletsTest : public ::testing::Test {
 protected:
  void SetUp() override { bytes_ = *EncodeMeshToDraco(testing::Grid(40)); }  // 3,200 faces

  // `max_event_bytes` 0: the server's default (3 MiB).
  void StartServer(size_t max_event_bytes = 0) {
    server::ServerOptions options;
    options.gpu = server::GpuMode::kOff;
    if (max_event_bytes != 0) options.max_event_bytes = max_event_bytes;
    server_ = testing::StartServer(options);
    ASSERT_TRUE(server_);
    channel_ = testing::ChannelTo(*server_);
  }

  void ExpectSame(v1::Algorithm algorithm, uint32_t clusters, uint32_t batch_triplets,
                  bool expect_split) {
    Seen varint_seen, packed_seen;
    absl::StatusOr<client::JobResult> varint =
        RunWith(channel_, algorithm, clusters, batch_triplets, false, bytes_, varint_seen);
    absl::StatusOr<client::JobResult> packed =
        RunWith(channel_, algorithm, clusters, batch_triplets, true, bytes_, packed_seen);
    ASSERT_TRUE(varint.ok()) << varint.status();
    ASSERT_TRUE(packed.ok()) << packed.status();
    EXPECT_GT(varint->hierarchy.num_levels(), 1u);
    ExpectSameHierarchy(varint->hierarchy, packed->hierarchy);
    EXPECT_EQ(varint->done.triplets(), packed->done.triplets());
    EXPECT_EQ(varint->done.levels(), packed->done.levels());
    EXPECT_EQ(varint->done.final_clusters(), packed->done.final_clusters());
    EXPECT_EQ(varint_seen.repeated_batches, varint_seen.batches);
    EXPECT_GT(packed_seen.batches, 0);
    // Batches of levels without moves carry neither.
    EXPECT_EQ(packed_seen.repeated_batches, 0);
    EXPECT_GT(packed_seen.packed_batches, 0);
    if (expect_split) EXPECT_GT(packed_seen.continued_batches, 0);
  }

  std::unique_ptr<server::Server> server_;
  std::shared_ptr<grpc::Channel> channel_;
  std::string bytes_;
};

TEST_F(PackedTripletsTest, HcSameLevelsWithDefaultBatches) {
  StartServer();
  ExpectSame(v1::ALGORITHM_HC, 0, 0, false);
}

TEST_F(PackedTripletsTest, MlSameLevelsWithSmallBatches) {
  StartServer();
  ExpectSame(v1::ALGORITHM_ML, 0, 7, false);
}

TEST_F(PackedTripletsTest, MlSameLevelsWithBatchesSplitUnderASmallMessageLimit) {
  // 2 KiB messages (at most ~160 packed triplets): the store cuts batches and levels.
  StartServer(2 << 10);
  ExpectSame(v1::ALGORITHM_ML, 0, 0, true);
}

TEST_F(PackedTripletsTest, EmloSameResultWithItsLevelSplit) {
  StartServer(2 << 10);
  ExpectSame(v1::ALGORITHM_EMLO, 20, 0, true);
}

}  // namespace
}  // namespace mlclust
