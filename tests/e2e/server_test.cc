// End-to-end tests: a real server on 127.0.0.1:0, real Draco bytes over real gRPC.
#include "server/server.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <zlib.h>

#include <algorithm>
#include <future>
#include <limits>
#include <random>
#include <thread>

#include "absl/container/flat_hash_set.h"
#include "client/client.h"
#include "core/cluster/point_clustering.h"
#include "core/energy/energies.h"
#include "core/hierarchy/model_selection.h"
#include "core/io/draco_codec.h"
#include "core/io/mesh_io.h"
#include "core/mesh/face_measures.h"
#include "grpc/health/v1/health.grpc.pb.h"
#include "grpcpp/grpcpp.h"
#include "mlclust/v1/mlclust.grpc.pb.h"
#include "server/job_options.h"
#include "tests/fixtures/foreign_draco.h"
#include "tests/fixtures/test_meshes.h"
#include "tests/fixtures/test_server.h"

namespace mlclust {
namespace {

using ::testing::HasSubstr;

class ServerTest : public ::testing::Test {
 protected:
  void StartServer(server::ServerOptions options = {}) {
    server_ = testing::StartServer(std::move(options));
    ASSERT_TRUE(server_);
    ASSERT_GT(server_->port(), 0);
    channel_ = testing::ChannelTo(*server_);
  }
  void SetUp() override { StartServer(); }

  static v1::JobSpec HcSpec() {
    v1::JobSpec spec;
    spec.set_input_kind(v1::INPUT_KIND_DRACO_MESH);
    spec.set_algorithm(v1::ALGORITHM_HC);
    spec.set_energy(v1::ENERGY_CVD);
    return spec;
  }

  absl::StatusOr<client::JobResult> Run(const TriangleMesh& mesh, v1::JobSpec spec = HcSpec(),
                                        client::RunOptions options = {}) {
    absl::StatusOr<std::string> bytes = EncodeMeshToDraco(mesh);
    if (!bytes.ok()) return bytes.status();
    return client::RunJob(channel_, spec, *bytes, options);
  }

  bool Healthy() {
    auto stub = grpc::health::v1::Health::NewStub(channel_);
    grpc::ClientContext context;
    grpc::health::v1::HealthCheckRequest request;
    request.set_service("mlclust.v1.Clustering");
    grpc::health::v1::HealthCheckResponse response;
    return stub->Check(&context, request, &response).ok() &&
           response.status() == grpc::health::v1::HealthCheckResponse::SERVING;
  }

  v1::Stats GetStats() {
    auto stub = v1::Clustering::NewStub(channel_);
    grpc::ClientContext context;
    v1::Stats stats;
    EXPECT_TRUE(stub->GetStats(&context, v1::GetStatsRequest(), &stats).ok());
    return stats;
  }

  std::unique_ptr<server::Server> server_;
  std::shared_ptr<grpc::Channel> channel_;
};

TriangleMesh Fandisk() {
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(testing::DataPath("fandisk.off"));
  EXPECT_TRUE(mesh.ok()) << mesh.status();
  return *std::move(mesh);
}

// Checks a received hierarchy against the client's own mesh: at sampled levels the rebuilt
// labels have the reported cluster count and the reported energy, recomputed from the
// mesh and labels alone. Labels attached to the wrong faces would fail both checks.
void ExpectLevelsMatchMesh(const HierarchyLog& log, const TriangleMesh& mesh) {
  ASSERT_EQ(log.num_elements(), mesh.num_faces());
  const FaceMeasures measures = ComputeFaceMeasures(mesh);
  const size_t n = log.num_levels();
  for (size_t level : {size_t{0}, size_t{1}, n / 3, n - 100, n - 10, n - 1}) {
    absl::StatusOr<std::vector<ClusterId>> labels = log.LabelsAt(level);
    ASSERT_TRUE(labels.ok()) << labels.status();
    absl::flat_hash_set<uint32_t> distinct;
    for (ClusterId c : *labels) distinct.insert(c.value());
    EXPECT_EQ(distinct.size(), log.cluster_count(level)) << "level " << level;
    const double direct = CvdEnergyDirect(measures, *labels);
    EXPECT_NEAR(log.energy(level), direct, 1e-9 * direct + 1e-12) << "level " << level;
  }
}

TEST_F(ServerTest, FandiskHierarchyArrivesWhole) {
  const TriangleMesh mesh = Fandisk();
  std::vector<v1::JobEvent::EventCase> kinds;
  client::RunOptions options;
  options.on_event = [&](const v1::JobEvent& e) { kinds.push_back(e.event_case()); };
  absl::StatusOr<client::JobResult> result = Run(mesh, HcSpec(), options);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_THAT(result->job_id, HasSubstr("job-"));
  EXPECT_EQ(result->hierarchy.num_levels(), mesh.num_faces());
  EXPECT_EQ(result->done.levels(), mesh.num_faces());
  EXPECT_EQ(result->done.triplets(), result->hierarchy.num_moves());
  EXPECT_EQ(result->done.final_clusters(), 1u);
  ExpectLevelsMatchMesh(result->hierarchy, mesh);
  // Accepted first, done last, and the levels batched (far fewer messages than levels).
  ASSERT_GE(kinds.size(), 3u);
  EXPECT_EQ(kinds.front(), v1::JobEvent::kAccepted);
  EXPECT_EQ(kinds.back(), v1::JobEvent::kDone);
  const size_t batches = std::count(kinds.begin(), kinds.end(), v1::JobEvent::kLevels);
  EXPECT_GE(batches, 1u);
  EXPECT_LT(batches, mesh.num_faces() / 100);
}

TEST_F(ServerTest, ShuffledFacesKeepTheirIds) {
  TriangleMesh mesh = Fandisk();
  std::vector<uint32_t> order(mesh.num_faces());
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), std::mt19937(7));
  TriangleMesh shuffled;
  shuffled.positions = mesh.positions;
  for (uint32_t f : order) {
    shuffled.indices.insert(shuffled.indices.end(), &mesh.indices[3 * f], &mesh.indices[3 * f + 3]);
  }
  absl::StatusOr<client::JobResult> result = Run(shuffled);
  ASSERT_TRUE(result.ok()) << result.status();
  ExpectLevelsMatchMesh(result->hierarchy, shuffled);
  // The first merge joins two faces that touch in the client's own face order.
  const LevelMoves first = result->hierarchy.level(1);
  ASSERT_EQ(first.element.size(), 1u);
  absl::StatusOr<FaceAdjacency> adjacency = BuildFaceAdjacency(shuffled);
  ASSERT_TRUE(adjacency.ok());
  const auto& around = adjacency->neighbours[first.element[0]];
  EXPECT_TRUE(around[0] == FaceId(first.to_cluster[0]) ||
              around[1] == FaceId(first.to_cluster[0]) || around[2] == FaceId(first.to_cluster[0]));
}

TEST_F(ServerTest, BadMeshesAreRefusedWithAMessageAndTheServerKeepsServing) {
  struct Case {
    std::string name;
    TriangleMesh mesh;
    std::string message;
  };
  TriangleMesh with_nan = testing::TwoTriangles();
  with_nan.positions[4] = std::numeric_limits<float>::quiet_NaN();
  std::vector<Case> cases = {
      {"non-manifold edge",
       testing::MakeMesh({0, 0, 0, 1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1},
                         {0, 1, 2, 1, 0, 3, 0, 1, 4}),
       "non-manifold edge"},
      {"NaN", with_nan, "non-finite coordinate"},
      {"bow-tie", testing::BowTie(), "non-manifold vertex"},
  };
  for (const Case& c : cases) {
    absl::StatusOr<client::JobResult> result = Run(c.mesh);
    EXPECT_EQ(result.status().code(), absl::StatusCode::kInvalidArgument) << c.name;
    EXPECT_THAT(result.status().message(), HasSubstr(c.message)) << c.name;
  }
  EXPECT_TRUE(Healthy());
  absl::StatusOr<client::JobResult> good = Run(testing::Grid(20));
  ASSERT_TRUE(good.ok()) << good.status();
  EXPECT_EQ(good->done.final_clusters(), 1u);
  EXPECT_GE(GetStats().jobs_failed(), 3u);
}

TEST_F(ServerTest, GarbageAndTruncatedDracoAreInvalidArgument) {
  std::mt19937 rng(11);
  std::string garbage(4096, '\0');
  for (char& c : garbage) c = static_cast<char>(rng());
  absl::StatusOr<client::JobResult> result = client::RunJob(channel_, HcSpec(), garbage);
  EXPECT_EQ(result.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(result.status().message(), HasSubstr("input mesh"));

  absl::StatusOr<std::string> bytes = EncodeMeshToDraco(testing::Grid(10));
  ASSERT_TRUE(bytes.ok());
  const std::string truncated = bytes->substr(0, bytes->size() / 2);
  result = client::RunJob(channel_, HcSpec(), truncated);
  EXPECT_EQ(result.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE(Healthy());
}

TEST_F(ServerTest, BadSpecsAreRefused) {
  absl::StatusOr<std::string> bytes = EncodeMeshToDraco(testing::Grid(4));
  ASSERT_TRUE(bytes.ok());
  v1::JobSpec spec = HcSpec();
  spec.set_clusters(1000);  // more than the 32 faces
  absl::StatusOr<client::JobResult> result = client::RunJob(channel_, spec, *bytes);
  EXPECT_EQ(result.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(result.status().message(), HasSubstr("clusters: 1000"));

  spec = HcSpec();
  spec.set_input_kind(v1::INPUT_KIND_UNSPECIFIED);
  EXPECT_EQ(client::RunJob(channel_, spec, *bytes).status().code(),
            absl::StatusCode::kInvalidArgument);

  spec = HcSpec();
  spec.set_device("tpu");
  result = client::RunJob(channel_, spec, *bytes);
  EXPECT_EQ(result.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(result.status().message(), HasSubstr("device"));

  // Mesh bytes sent as points without their dimension.
  spec = HcSpec();
  spec.set_input_kind(v1::INPUT_KIND_POINTS_F32);
  spec.set_energy(v1::ENERGY_UNSPECIFIED);
  result = client::RunJob(channel_, spec, *bytes);
  EXPECT_EQ(result.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(result.status().message(), HasSubstr("point_dims"));

  // The hierarchy stops early at `clusters`.
  spec = HcSpec();
  spec.set_clusters(5);
  result = client::RunJob(channel_, spec, *bytes);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_EQ(result->done.final_clusters(), 5u);
}

// Sends `bytes` under `spec` chunk by chunk and returns the call's status and whether an
// Accepted event came before it.
std::pair<grpc::Status, bool> SendAndWatchForAccepted(const std::shared_ptr<grpc::Channel>& channel,
                                                      v1::JobSpec spec, const std::string& bytes) {
  auto stub = v1::Clustering::NewStub(channel);
  grpc::ClientContext context;
  auto stream = stub->Run(&context);
  v1::RunRequest first;
  spec.set_input_bytes(bytes.size());
  *first.mutable_spec() = spec;
  first.set_chunk(bytes.substr(0, bytes.size() / 2));
  v1::RunRequest second;
  second.set_chunk(bytes.substr(bytes.size() / 2));
  stream->Write(first);
  stream->Write(second);
  stream->WritesDone();
  v1::JobEvent event;
  bool accepted = false;
  while (stream->Read(&event)) accepted = accepted || event.has_accepted();
  return {stream->Finish(), accepted};
}

// Issue 25: what the spec and the payload's header contradict is refused before Accepted
// (INVALID_ARGUMENT naming what and where), not as the job's error after it.
TEST_F(ServerTest, ContradictoryPayloadsAreRefusedBeforeAccepted) {
  const TriangleMesh grid = testing::Grid(6);
  DracoEncodeOptions with_ids;
  with_ids.method = DracoMethod::kEdgebreaker;
  with_ids.write_face_ids = true;
  const absl::StatusOr<std::string> edgebreaker = EncodeMeshToDraco(grid, with_ids);
  ASSERT_TRUE(edgebreaker.ok()) << edgebreaker.status();
  // As a foreign encoder writes it: the sequential method with the face id attribute.
  std::vector<uint32_t> ids(grid.num_faces());
  for (uint32_t f = 0; f < ids.size(); ++f) ids[f] = f;
  const std::string sequential_with_ids =
      testing::EncodeLikeForeignEncoder(grid, ids, draco::MESH_SEQUENTIAL_ENCODING);
  ASSERT_EQ(sequential_with_ids.substr(0, 5), "DRACO");
  auto [status, accepted] = SendAndWatchForAccepted(channel_, HcSpec(), sequential_with_ids);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("byte 8"));
  EXPECT_THAT(status.error_message(), HasSubstr("sequential"));
  EXPECT_THAT(status.error_message(), HasSubstr("mlclust_face_id"));
  EXPECT_FALSE(accepted);

  // A mesh job whose payload is not Draco data.
  std::tie(status, accepted) = SendAndWatchForAccepted(channel_, HcSpec(), std::string(64, 'x'));
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("input mesh: the payload does not start"));
  EXPECT_FALSE(accepted);

  // Points that are not a whole number of points, refused from the spec alone.
  v1::JobSpec points;
  points.set_input_kind(v1::INPUT_KIND_POINTS_F32);
  points.set_point_dims(3);
  points.set_algorithm(v1::ALGORITHM_ML);
  std::tie(status, accepted) = SendAndWatchForAccepted(channel_, points, std::string(16, '\0'));
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("spec.input_bytes: 16 bytes"));
  EXPECT_FALSE(accepted);

  // The same edgebreaker payload as sent runs.
  std::tie(status, accepted) = SendAndWatchForAccepted(channel_, HcSpec(), *edgebreaker);
  EXPECT_TRUE(status.ok()) << status.error_message();
  EXPECT_TRUE(accepted);
  EXPECT_TRUE(Healthy());
}

TEST_F(ServerTest, ChunkedUploadOfManySmallChunks) {
  const TriangleMesh mesh = testing::Grid(30);
  client::RunOptions options;
  options.chunk_bytes = 97;  // many messages, none aligned to anything
  absl::StatusOr<client::JobResult> result = Run(mesh, HcSpec(), options);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_EQ(result->hierarchy.num_levels(), mesh.num_faces());
}

// JobSpec.input_crc32: chunks that arrive reordered (a broken client) give an input of the
// right size but the wrong checksum, refused before queueing; the same chunks in order run.
TEST_F(ServerTest, AnInputWhoseChecksumDiffersIsRefused) {
  const absl::StatusOr<std::string> bytes = EncodeMeshToDraco(testing::Grid(10));
  ASSERT_TRUE(bytes.ok());
  const size_t half = bytes->size() / 2;
  auto send = [&](bool swap_halves) {
    auto stub = v1::Clustering::NewStub(channel_);
    grpc::ClientContext context;
    auto stream = stub->Run(&context);
    v1::RunRequest first;
    *first.mutable_spec() = HcSpec();
    first.mutable_spec()->set_input_bytes(bytes->size());
    first.mutable_spec()->set_input_crc32(static_cast<uint32_t>(
        crc32_z(0, reinterpret_cast<const Bytef*>(bytes->data()), bytes->size())));
    first.set_chunk(swap_halves ? bytes->substr(half) : bytes->substr(0, half));
    v1::RunRequest second;
    second.set_chunk(swap_halves ? bytes->substr(0, half) : bytes->substr(half));
    stream->Write(first);
    stream->Write(second);
    stream->WritesDone();
    v1::JobEvent event;
    bool done = false;
    while (stream->Read(&event)) done = done || event.has_done();
    const grpc::Status status = stream->Finish();
    return std::make_pair(status, done);
  };
  const auto [reordered, reordered_done] = send(/*swap_halves=*/true);
  EXPECT_EQ(reordered.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(reordered.error_message(), HasSubstr("input checksum"));
  EXPECT_FALSE(reordered_done);
  const auto [in_order, in_order_done] = send(/*swap_halves=*/false);
  EXPECT_TRUE(in_order.ok()) << in_order.error_message();
  EXPECT_TRUE(in_order_done);
  EXPECT_TRUE(Healthy());
}

TEST(ServerLimitsTest, InputOverTheLimitIsResourceExhaustedBeforeUpload) {
  server::ServerOptions options;
  options.max_input_bytes = 1000;
  std::unique_ptr<server::Server> server = testing::StartServer(options);
  ASSERT_TRUE(server);
  auto channel = testing::ChannelTo(*server);
  absl::StatusOr<std::string> bytes = EncodeMeshToDraco(testing::Grid(30));
  ASSERT_TRUE(bytes.ok());
  ASSERT_GT(bytes->size(), 1000u);
  v1::JobSpec spec;
  spec.set_input_kind(v1::INPUT_KIND_DRACO_MESH);
  absl::StatusOr<client::JobResult> result = client::RunJob(channel, spec, *bytes);
  EXPECT_EQ(result.status().code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(result.status().message(), HasSubstr("limit of 1000 bytes"));
}

TEST(ServerLimitsTest, FullQueueIsResourceExhaustedAtOnceAndOthersFinish) {
  server::ServerOptions options;
  options.queue_capacity = 1;
  options.gpu = server::GpuMode::kOff;
  std::unique_ptr<server::Server> server = testing::StartServer(options);
  ASSERT_TRUE(server);
  auto channel = testing::ChannelTo(*server);
  absl::StatusOr<std::string> bytes = EncodeMeshToDraco(testing::Grid(150));  // 45k faces
  ASSERT_TRUE(bytes.ok());
  v1::JobSpec spec;
  spec.set_input_kind(v1::INPUT_KIND_DRACO_MESH);
  std::vector<std::future<absl::StatusOr<client::JobResult>>> jobs;
  for (int i = 0; i < 6; ++i) {
    jobs.push_back(
        std::async(std::launch::async, [&] { return client::RunJob(channel, spec, *bytes); }));
  }
  int succeeded = 0, refused = 0;
  for (auto& job : jobs) {
    absl::StatusOr<client::JobResult> result = job.get();
    if (result.ok()) {
      ++succeeded;
      EXPECT_EQ(result->done.final_clusters(), 1u);
    } else {
      EXPECT_EQ(result.status().code(), absl::StatusCode::kResourceExhausted) << result.status();
      EXPECT_THAT(result.status().message(), HasSubstr("queue is full"));
      ++refused;
    }
  }
  EXPECT_GE(succeeded, 1);
  EXPECT_GE(refused, 1);
}

TEST_F(ServerTest, DeadlineCancelsTheJobAndTheServerGoesOn) {
  const TriangleMesh big = testing::Grid(500);  // 500k faces: seconds of work
  client::RunOptions options;
  options.deadline = absl::Milliseconds(200);
  absl::StatusOr<client::JobResult> result = Run(big, HcSpec(), options);
  EXPECT_EQ(result.status().code(), absl::StatusCode::kDeadlineExceeded) << result.status();
  absl::StatusOr<client::JobResult> next = Run(testing::Grid(10));
  ASSERT_TRUE(next.ok()) << next.status();
  // The cancelled job is counted once the worker has noticed (within 0.4 s on an idle
  // machine; the wait is long because CI's 2 cores may be busy with other tests).
  for (int i = 0; i < 600 && GetStats().jobs_cancelled() == 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  EXPECT_EQ(GetStats().jobs_cancelled(), 1u);
  EXPECT_EQ(GetStats().jobs_succeeded(), 1u);
}

TEST_F(ServerTest, EmbeddedChannelGivesTheSameHierarchyAsTcp) {
  const TriangleMesh mesh = testing::Grid(25);
  absl::StatusOr<client::JobResult> tcp = Run(mesh);
  ASSERT_TRUE(tcp.ok());
  absl::StatusOr<std::string> bytes = EncodeMeshToDraco(mesh);
  ASSERT_TRUE(bytes.ok());
  absl::StatusOr<client::JobResult> embedded =
      client::RunJob(server_->InProcessChannel(), HcSpec(), *bytes);
  ASSERT_TRUE(embedded.ok()) << embedded.status();
  ASSERT_EQ(tcp->hierarchy.num_levels(), embedded->hierarchy.num_levels());
  const size_t last = tcp->hierarchy.num_levels() - 1;
  EXPECT_EQ(*tcp->hierarchy.LabelsAt(last / 2), *embedded->hierarchy.LabelsAt(last / 2));
  EXPECT_EQ(tcp->hierarchy.energy(last), embedded->hierarchy.energy(last));
}

TEST_F(ServerTest, StatsReportTheQueueAndTheDevice) {
  ASSERT_TRUE(Run(testing::Grid(5)).ok());
  const v1::Stats stats = GetStats();
  EXPECT_EQ(stats.jobs_succeeded(), 1u);
  EXPECT_EQ(stats.jobs_accepted(), 1u);
  EXPECT_EQ(stats.queue_capacity(), 16u);
  EXPECT_EQ(stats.gpu_available(), !server_->gl_renderer().empty());
  EXPECT_EQ(stats.gl_renderer(), server_->gl_renderer());
  std::printf("GL renderer: '%s' (%s)\n", stats.gl_renderer().c_str(),
              server_->gl_unavailable_reason().c_str());
}

}  // namespace
}  // namespace mlclust

namespace mlclust {
namespace {

v1::JobSpec Spec(v1::Algorithm algorithm, v1::Energy energy = v1::ENERGY_CVD) {
  v1::JobSpec spec;
  spec.set_input_kind(v1::INPUT_KIND_DRACO_MESH);
  spec.set_algorithm(algorithm);
  spec.set_energy(energy);
  return spec;
}

class AlgorithmsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    server_ = testing::StartServer();
    ASSERT_TRUE(server_);
    channel_ = testing::ChannelTo(*server_);
    mesh_ = *ReadMeshFile(testing::DataPath("elephant.off"));
    bytes_ = *EncodeMeshToDraco(mesh_);
  }
  absl::StatusOr<client::JobResult> Run(const v1::JobSpec& spec) {
    return client::RunJob(channel_, spec, bytes_);
  }
  std::unique_ptr<server::Server> server_;
  std::shared_ptr<grpc::Channel> channel_;
  TriangleMesh mesh_;
  std::string bytes_;
};

TEST_F(AlgorithmsTest, MlAndPmlHierarchiesMatchTheirEnergies) {
  for (v1::Algorithm algorithm : {v1::ALGORITHM_ML, v1::ALGORITHM_PML}) {
    for (v1::Energy energy : {v1::ENERGY_CVD, v1::ENERGY_PLANAR, v1::ENERGY_MWCVD_AREA}) {
      v1::JobSpec spec = Spec(algorithm, energy);
      if (algorithm == v1::ALGORITHM_PML) (*spec.mutable_options())["pml-until"] = "300";
      absl::StatusOr<client::JobResult> result = Run(spec);
      ASSERT_TRUE(result.ok()) << result.status();
      const HierarchyLog& log = result->hierarchy;
      ASSERT_GT(log.num_levels(), 2u);
      EXPECT_EQ(log.cluster_count(log.num_levels() - 1), 1u);
      MeshEnergyOptions options;
      options.kind = *server::MeshEnergyFromWire(energy);
      for (size_t level : {log.num_levels() / 2, log.num_levels() - 20}) {
        auto labels = log.LabelsAt(level);
        ASSERT_TRUE(labels.ok());
        const double direct =
            WithMeshEnergy(options, mesh_, ComputeFaceMeasures(mesh_),
                           [&](const auto& e) { return EnergyFromProxies(e, *labels); });
        EXPECT_NEAR(log.energy(level), direct, 1e-7 * direct)
            << v1::Algorithm_Name(algorithm) << " " << v1::Energy_Name(energy);
      }
    }
  }
}

TEST_F(AlgorithmsTest, LevelRangeSendsASnapshotThenOnlyLevelsInRange) {
  v1::JobSpec full = Spec(v1::ALGORITHM_ML);
  absl::StatusOr<client::JobResult> all = Run(full);
  ASSERT_TRUE(all.ok());
  v1::JobSpec spec = Spec(v1::ALGORITHM_ML);
  spec.set_levels_high(500);
  spec.set_levels_low(100);
  absl::StatusOr<client::JobResult> range = Run(spec);
  ASSERT_TRUE(range.ok()) << range.status();
  const HierarchyLog& log = range->hierarchy;
  ASSERT_EQ(log.num_levels(), 401u);  // 500, 499, ..., 100
  EXPECT_EQ(log.cluster_count(0), 500u);
  EXPECT_EQ(log.cluster_count(400), 100u);
  // Every level in range equals the same level of the full run, labels and energy.
  const size_t offset = *all->hierarchy.LastLevelWith(500);
  for (size_t level : {size_t{0}, size_t{1}, size_t{250}, size_t{400}}) {
    EXPECT_EQ(*log.LabelsAt(level), *all->hierarchy.LabelsAt(offset + level)) << level;
    EXPECT_DOUBLE_EQ(log.energy(level), all->hierarchy.energy(offset + level));
  }
  EXPECT_LT(range->done.triplets(), all->done.triplets());
  spec.set_levels_high(50);
  spec.set_levels_low(100);
  EXPECT_EQ(Run(spec).status().code(), absl::StatusCode::kInvalidArgument);
  spec = Spec(v1::ALGORITHM_EMLO);
  spec.set_clusters(10);
  spec.set_levels_high(20);
  EXPECT_EQ(Run(spec).status().code(), absl::StatusCode::kInvalidArgument);
}

TEST_F(AlgorithmsTest, SingleLevelAlgorithmsSendStartAndResult) {
  for (v1::Algorithm algorithm : {v1::ALGORITHM_EMLO, v1::ALGORITHM_BB}) {
    v1::JobSpec spec = Spec(algorithm, v1::ENERGY_PLANAR);
    spec.set_clusters(40);
    (*spec.mutable_options())["init"] = "random";
    spec.set_seed(3);
    absl::StatusOr<client::JobResult> result = Run(spec);
    ASSERT_TRUE(result.ok()) << result.status();
    ASSERT_EQ(result->hierarchy.num_levels(), 2u);
    EXPECT_EQ(result->hierarchy.cluster_count(1), 40u);
    EXPECT_LT(result->hierarchy.energy(1), result->hierarchy.energy(0));
    MeshEnergyOptions planar;
    planar.kind = MeshEnergyKind::kPlanar;
    EXPECT_NEAR(result->hierarchy.energy(1),
                MeshEnergyOfLabels(planar, mesh_, *result->hierarchy.LabelsAt(1)),
                1e-9 * result->hierarchy.energy(1));
  }
}

TEST_F(AlgorithmsTest, BadOptionsAreRefusedNamingTheOption) {
  struct Case {
    v1::Algorithm algorithm;
    uint32_t clusters;
    std::map<std::string, std::string> options;
    absl::StatusCode code;
    std::string message;
  };
  const std::vector<Case> cases = {
      {v1::ALGORITHM_EMLO, 0, {}, absl::StatusCode::kInvalidArgument, "clusters"},
      {v1::ALGORITHM_EMLO, 100000, {}, absl::StatusCode::kInvalidArgument, "clusters"},
      {v1::ALGORITHM_EMLO, 10, {{"gamma", "-1"}}, absl::StatusCode::kInvalidArgument, "gamma"},
      {v1::ALGORITHM_EMLO, 10, {{"init", "magic"}}, absl::StatusCode::kInvalidArgument, "init"},
      {v1::ALGORITHM_BB, 10, {{"threads", "x"}}, absl::StatusCode::kInvalidArgument, "threads"},
      {v1::ALGORITHM_ML,
       0,
       {{"p-percent", "120"}},
       absl::StatusCode::kInvalidArgument,
       "p-percent"},
      {v1::ALGORITHM_ML, 0, {{"optimizer", "sa"}}, absl::StatusCode::kInvalidArgument, "optimizer"},
      {v1::ALGORITHM_ML, 0, {{"colour", "red"}}, absl::StatusCode::kInvalidArgument, "colour"},
      {v1::ALGORITHM_KMEANS, 10, {}, absl::StatusCode::kUnimplemented, "ALGORITHM_KMEANS"},
  };
  for (const Case& c : cases) {
    v1::JobSpec spec = Spec(c.algorithm);
    spec.set_clusters(c.clusters);
    for (const auto& [name, value] : c.options) (*spec.mutable_options())[name] = value;
    absl::Status status = Run(spec).status();
    EXPECT_EQ(status.code(), c.code) << c.message << ": " << status;
    EXPECT_THAT(std::string(status.message()), HasSubstr(c.message));
  }
}

TEST_F(AlgorithmsTest, ElbowIsReported) {
  absl::StatusOr<client::JobResult> result = Run(Spec(v1::ALGORITHM_ML));
  ASSERT_TRUE(result.ok());
  // Whatever the mesh, the summary names at most five elbows, each a level's count.
  EXPECT_LE(result->done.elbow_cluster_counts_size(), 5);
  for (uint32_t k : result->done.elbow_cluster_counts()) {
    EXPECT_TRUE(result->hierarchy.LastLevelWith(k).has_value()) << k;
  }
}

}  // namespace
}  // namespace mlclust

namespace mlclust {
namespace {

std::string Float32Bytes(const PointSet& points) {
  return std::string(reinterpret_cast<const char*>(points.values.data()),
                     points.values.size() * sizeof(float));
}

PointSet Grid3d(int n) {
  PointSet points;
  points.dims = 3;
  for (int x = 0; x < n; ++x) {
    for (int y = 0; y < n; ++y) {
      for (int z = 0; z < n; ++z) {
        // Two well separated groups along x.
        points.values.insert(points.values.end(), {static_cast<float>(x + (x >= n / 2 ? 40 : 0)),
                                                   static_cast<float>(y), static_cast<float>(z)});
      }
    }
  }
  return points;
}

TEST_F(AlgorithmsTest, PointHierarchiesAndLnKmeansOverTheWire) {
  const PointSet points = Grid3d(12);  // 1728 points
  for (v1::Algorithm algorithm : {v1::ALGORITHM_HC, v1::ALGORITHM_ML, v1::ALGORITHM_PML}) {
    v1::JobSpec spec;
    spec.set_input_kind(v1::INPUT_KIND_POINTS_F32);
    spec.set_point_dims(3);
    spec.set_algorithm(algorithm);
    (*spec.mutable_options())["grid"] = "6";
    absl::StatusOr<client::JobResult> result = client::RunJob(channel_, spec, Float32Bytes(points));
    ASSERT_TRUE(result.ok()) << result.status();
    const HierarchyLog& log = result->hierarchy;
    EXPECT_EQ(log.cluster_count(log.num_levels() - 1), 1u);
    const std::optional<size_t> two = log.FirstLevelWithAtMost(2);
    ASSERT_TRUE(two.has_value());
    auto labels = log.LabelsAt(*two);
    ASSERT_TRUE(labels.ok());
    EXPECT_NEAR(log.energy(*two), PointEnergy(points, *labels), 1e-6 * log.energy(*two));
    if (log.cluster_count(*two) == 2) {
      // The two groups, 40 apart, are the two clusters.
      EXPECT_NE((*labels)[0], (*labels)[points.num_points() - 1]);
    }
  }
  v1::JobSpec spec;
  spec.set_input_kind(v1::INPUT_KIND_POINTS_F32);
  spec.set_point_dims(3);
  spec.set_algorithm(v1::ALGORITHM_LN_KMEANS);
  spec.set_clusters(8);
  absl::StatusOr<client::JobResult> result = client::RunJob(channel_, spec, Float32Bytes(points));
  ASSERT_TRUE(result.ok()) << result.status();
  ASSERT_EQ(result->hierarchy.num_levels(), 2u);
  EXPECT_LE(result->hierarchy.energy(1), result->hierarchy.energy(0));
}

TEST_F(AlgorithmsTest, PointSummaryNamesTheBicOfEveryLevelEvenOutsideTheRangeSent) {
  const PointSet points = Grid3d(12);
  v1::JobSpec spec;
  spec.set_input_kind(v1::INPUT_KIND_POINTS_F32);
  spec.set_point_dims(3);
  spec.set_algorithm(v1::ALGORITHM_ML);
  (*spec.mutable_options())["grid"] = "6";
  absl::StatusOr<client::JobResult> full = client::RunJob(channel_, spec, Float32Bytes(points));
  ASSERT_TRUE(full.ok()) << full.status();
  // The same choice from the levels the client received.
  const HierarchyLog& log = full->hierarchy;
  BicLevelRecorder recorder;
  ASSERT_TRUE(recorder.OnStart(log.start_labels(), log.cluster_count(0), log.energy(0)).ok());
  for (size_t l = 1; l < log.num_levels(); ++l) ASSERT_TRUE(recorder.OnLevel(log.level(l)).ok());
  absl::StatusOr<BicChoice> choice = ChooseByBic(recorder.levels(), recorder.num_points(), 3);
  ASSERT_TRUE(choice.ok()) << choice.status();
  EXPECT_EQ(full->done.bic_best_cluster_count(), choice->best_k);
  EXPECT_EQ(full->done.bic_first_decrease_cluster_count(), choice->first_decrease_k);
  EXPECT_EQ(full->done.bic_merging_first_decrease_cluster_count(),
            choice->merging_first_decrease_k);
  EXPECT_NEAR(full->done.bic_best(), choice->bic[choice->best_level],
              1e-9 * std::abs(choice->bic[choice->best_level]));
  ASSERT_GT(choice->best_k, 3u);
  // Only the levels with at most 3 clusters sent: the summary still scores every level.
  spec.set_levels_high(3);
  absl::StatusOr<client::JobResult> part = client::RunJob(channel_, spec, Float32Bytes(points));
  ASSERT_TRUE(part.ok()) << part.status();
  EXPECT_LE(part->hierarchy.cluster_count(0), 3u);
  EXPECT_EQ(part->done.bic_best_cluster_count(), choice->best_k);
  EXPECT_EQ(part->done.bic_first_decrease_cluster_count(), choice->first_decrease_k);
  EXPECT_EQ(part->done.bic_merging_first_decrease_cluster_count(),
            choice->merging_first_decrease_k);
}

TEST_F(AlgorithmsTest, PointsFromOneTo64DimensionsOverTheWire) {
  // Three groups 30 apart along the first axis (and noise on every axis).
  for (uint32_t d : {1u, 64u}) {
    PointSet points;
    points.dims = d;
    std::mt19937 random(d);
    std::normal_distribution<float> noise(0.0f, 1.0f);
    for (int i = 0; i < 900; ++i) {
      for (uint32_t j = 0; j < d; ++j) {
        points.values.push_back(noise(random) + (j == 0 ? 30.0f * (i % 3) : 0.0f));
      }
    }
    v1::JobSpec spec;
    spec.set_input_kind(v1::INPUT_KIND_POINTS_F32);
    spec.set_point_dims(d);
    spec.set_algorithm(v1::ALGORITHM_ML);
    absl::StatusOr<client::JobResult> ml = client::RunJob(channel_, spec, Float32Bytes(points));
    ASSERT_TRUE(ml.ok()) << d << ": " << ml.status();
    EXPECT_EQ(ml->done.bic_best_cluster_count(), 3u) << d;
    const std::optional<size_t> three = ml->hierarchy.LastLevelWith(3);
    ASSERT_TRUE(three.has_value()) << d;
    const std::vector<ClusterId> labels = *ml->hierarchy.LabelsAt(*three);
    for (int i = 3; i < 900; ++i) EXPECT_EQ(labels[i], labels[i % 3]) << d << " point " << i;
    spec.set_algorithm(v1::ALGORITHM_LN_KMEANS);
    spec.set_clusters(3);
    absl::StatusOr<client::JobResult> ln = client::RunJob(channel_, spec, Float32Bytes(points));
    ASSERT_TRUE(ln.ok()) << d << ": " << ln.status();
    const HierarchyLog& log = ln->hierarchy;
    EXPECT_NEAR(log.energy(log.num_levels() - 1), ml->hierarchy.energy(*three),
                1e-6 * ml->hierarchy.energy(*three))
        << d;
  }
}

TEST_F(AlgorithmsTest, BadPointBatchesAreRefused) {
  PointSet points = Grid3d(4);
  v1::JobSpec spec;
  spec.set_input_kind(v1::INPUT_KIND_POINTS_F32);
  spec.set_point_dims(3);
  spec.set_algorithm(v1::ALGORITHM_ML);
  std::string bytes = Float32Bytes(points);
  // Not a whole number of points.
  absl::Status status = client::RunJob(channel_, spec, bytes.substr(0, bytes.size() - 4)).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(status.message()), HasSubstr("whole number"));
  // A NaN, named by point and coordinate.
  points.values[3 * 5 + 1] = std::numeric_limits<float>::quiet_NaN();
  status = client::RunJob(channel_, spec, Float32Bytes(points)).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(status.message()), HasSubstr("point 5 coordinate 1"));
  // d = 0, a mesh energy, k > m.
  spec.set_point_dims(0);
  EXPECT_EQ(client::RunJob(channel_, spec, bytes).status().code(),
            absl::StatusCode::kInvalidArgument);
  spec.set_point_dims(3);
  spec.set_energy(v1::ENERGY_PLANAR);
  EXPECT_EQ(client::RunJob(channel_, spec, bytes).status().code(),
            absl::StatusCode::kInvalidArgument);
  spec.set_energy(v1::ENERGY_UNSPECIFIED);
  spec.set_algorithm(v1::ALGORITHM_LN_KMEANS);
  spec.set_clusters(1000);
  status = client::RunJob(channel_, spec, bytes).status();
  EXPECT_THAT(std::string(status.message()), HasSubstr("clusters"));
  // The server is still serving.
  spec.set_clusters(4);
  EXPECT_TRUE(client::RunJob(channel_, spec, bytes).ok());
}

}  // namespace
}  // namespace mlclust
