// The stream alone (issue 13): triplets/s from a server's LevelBatch messages into the
// client's HierarchyLog, without the engine in the way. The hierarchy is computed once (HC
// of MESH, as in wire_bench); a replay service then sends it as the server's sink does
// (the labels of level 0 as a snapshot, then LevelBatches of --batch triplets, repeated
// varint fields or JobSpec.packed_triplets' raw uint32) over gRPC on TCP loopback, and the
// real client::RunJob receives it (parse, checks, HierarchyLog). Also timed apart: building
// and serializing the batches (server side) and parsing them (client side) in one process.
//   stream_bench MESH [--batch 65536] [--repeats 5]
#include <algorithm>
#include <cstdio>
#include <cstring>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "bench/bench_util.h"
#include "client/client.h"
#include "core/cluster/multilevel.h"
#include "core/io/draco_codec.h"
#include "core/io/mesh_io.h"
#include "core/io/prepare_mesh.h"
#include "grpcpp/grpcpp.h"
#include "mlclust/v1/mlclust.grpc.pb.h"

namespace {

using mlclust::HierarchyLog;
using mlclust::LevelMoves;
namespace v1 = mlclust::v1;

void AppendPacked(std::string* bytes, std::span<const uint32_t> values) {
  const size_t old_size = bytes->size();
  bytes->resize(old_size + values.size_bytes());
  if (!values.empty()) std::memcpy(bytes->data() + old_size, values.data(), values.size_bytes());
}

// The events of `log` as the server's StreamingLevelSink sends them (levels whole; a
// packed level over `batch` triplets continues in the next batch).
std::vector<v1::JobEvent> BuildEvents(const HierarchyLog& log, uint32_t batch_triplets,
                                      bool packed) {
  std::vector<v1::JobEvent> events;
  v1::JobEvent snapshot_event;
  v1::LevelSnapshot* snapshot = snapshot_event.mutable_snapshot();
  snapshot->set_cluster_count(log.cluster_count(0));
  snapshot->set_energy(log.energy(0));
  snapshot->set_total_elements(static_cast<uint32_t>(log.num_elements()));
  snapshot->mutable_labels()->Reserve(static_cast<int>(log.num_elements()));
  for (mlclust::ClusterId label : log.start_labels()) snapshot->add_labels(label.value());
  events.push_back(std::move(snapshot_event));
  v1::JobEvent pending;
  size_t pending_triplets = 0;
  auto flush = [&] {
    if (!pending.has_levels()) return;
    events.push_back(std::move(pending));
    pending.Clear();
    pending_triplets = 0;
  };
  for (size_t l = 1; l < log.num_levels(); ++l) {
    const LevelMoves level = log.level(l);
    const size_t count = level.element.size();
    size_t done = 0;
    while (true) {
      v1::LevelBatch* batch = pending.mutable_levels();
      if (batch->cluster_count_size() == 0) batch->set_first_level(static_cast<uint32_t>(l));
      const size_t take = count;  // levels whole, as the sink sends them
      batch->add_cluster_count(level.cluster_count);
      batch->add_energy(level.energy);
      batch->add_source_level(static_cast<uint32_t>(l));
      if (packed) {
        AppendPacked(batch->mutable_packed_element(), level.element.subspan(done, take));
        AppendPacked(batch->mutable_packed_to_cluster(), level.to_cluster.subspan(done, take));
        AppendPacked(batch->mutable_packed_from_cluster(), level.from_cluster.subspan(done, take));
      } else {
        batch->mutable_element()->Add(level.element.begin(), level.element.end());
        batch->mutable_to_cluster()->Add(level.to_cluster.begin(), level.to_cluster.end());
        batch->mutable_from_cluster()->Add(level.from_cluster.begin(), level.from_cluster.end());
      }
      pending_triplets += take;
      done += take;
      batch->add_triplet_end(static_cast<uint32_t>(pending_triplets));
      if (done == count) break;
      batch->set_last_level_continues(true);
      flush();
    }
    if (pending_triplets >= batch_triplets) flush();
  }
  flush();
  v1::JobEvent done_event;
  done_event.mutable_done()->set_levels(static_cast<uint32_t>(log.num_levels()));
  done_event.mutable_done()->set_triplets(log.num_moves());
  done_event.set_final(true);
  events.push_back(std::move(done_event));
  return events;
}

// Answers Run by replaying one hierarchy, varint or packed as the spec asks.
class ReplayService final : public v1::Clustering::Service {
 public:
  ReplayService(const HierarchyLog& log, uint32_t batch_triplets)
      : log_(log), batch_triplets_(batch_triplets) {}

  grpc::Status Run(grpc::ServerContext* /*context*/,
                   grpc::ServerReaderWriter<v1::JobEvent, v1::RunRequest>* stream) override {
    v1::RunRequest request;
    bool packed = false;
    uint64_t expected = 1, received = 0;
    while (received < expected && stream->Read(&request)) {
      if (request.has_spec()) {
        packed = request.spec().packed_triplets();
        expected = request.spec().input_bytes();
      }
      received += request.chunk().size();
    }
    const absl::Time start = absl::Now();
    for (v1::JobEvent& event : BuildEvents(log_, batch_triplets_, packed)) {
      if (!stream->Write(event)) return grpc::Status(grpc::StatusCode::CANCELLED, "gone");
    }
    server_seconds = absl::ToDoubleSeconds(absl::Now() - start);
    return grpc::Status::OK;
  }

  double server_seconds = 0;

 private:
  const HierarchyLog& log_;
  const uint32_t batch_triplets_;
};

double Median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  return values[values.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  mlclust::bench::Args args(argc, argv, "usage: stream_bench MESH [--batch N] [--repeats R]");
  const uint32_t batch = std::max<uint32_t>(1, args.Get<uint32_t>("batch", 1 << 16));
  const int repeats = std::max(1, args.Get<int>("repeats", 5));
  const std::string path = args.Positional(0);
  if (!args.Done()) return 2;
  absl::StatusOr<mlclust::TriangleMesh> mesh = mlclust::ReadMeshFile(path);
  if (!mesh.ok()) return 1;
  absl::StatusOr<std::string> bytes = mlclust::EncodeMeshToDraco(*mesh);
  absl::StatusOr<mlclust::PreparedMesh> prepared = mlclust::PrepareDracoMesh(*bytes);
  if (!prepared.ok()) return 1;
  HierarchyLog log;
  mlclust::MultilevelOptions hc;
  hc.optimizer = mlclust::MultilevelOptions::Optimizer::kNone;
  if (!mlclust::RunMultilevel(mlclust::MakeMeshProblem(*prepared), hc, log).ok()) return 1;
  const double triplets = static_cast<double>(log.num_moves());
  std::printf("%s: %zu faces, HC: %zu levels, %zu triplets; batches of %u triplets; median of %d\n",
              path.c_str(), log.num_elements(), log.num_levels(), log.num_moves(), batch, repeats);

  ReplayService service(log, batch);
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
  builder.RegisterService(&service);
  builder.SetMaxSendMessageSize(-1);
  std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  if (!server) return 1;
  const std::shared_ptr<grpc::Channel> channel =
      mlclust::client::Connect(absl::StrCat("127.0.0.1:", port));

  for (const bool packed : {false, true}) {
    std::vector<double> build, serialize, parse, e2e, server_side;
    size_t wire_bytes = 0;
    for (int r = 0; r < repeats; ++r) {
      // Server side alone: build the messages, then serialize them.
      absl::Time t = absl::Now();
      std::vector<v1::JobEvent> events = BuildEvents(log, batch, packed);
      build.push_back(absl::ToDoubleSeconds(absl::Now() - t));
      t = absl::Now();
      std::vector<std::string> wire(events.size());
      for (size_t i = 0; i < events.size(); ++i) events[i].SerializeToString(&wire[i]);
      serialize.push_back(absl::ToDoubleSeconds(absl::Now() - t));
      wire_bytes = 0;
      for (const std::string& w : wire) wire_bytes += w.size();
      // Client side alone: parse every message.
      t = absl::Now();
      v1::JobEvent event;
      for (const std::string& w : wire) {
        if (!event.ParseFromString(w)) return 1;
      }
      parse.push_back(absl::ToDoubleSeconds(absl::Now() - t));
      // Through gRPC on TCP loopback into the client's HierarchyLog.
      v1::JobSpec spec;
      spec.set_input_kind(v1::INPUT_KIND_DRACO_MESH);
      mlclust::client::RunOptions options;
      options.packed_triplets = packed;
      t = absl::Now();
      absl::StatusOr<mlclust::client::JobResult> result =
          mlclust::client::RunJob(channel, spec, "x", options);
      e2e.push_back(absl::ToDoubleSeconds(absl::Now() - t));
      server_side.push_back(service.server_seconds);
      if (!result.ok()) {
        std::fprintf(stderr, "%s\n", result.status().ToString().c_str());
        return 1;
      }
      if (result->hierarchy.num_moves() != log.num_moves() ||
          result->hierarchy.num_levels() != log.num_levels() ||
          *result->hierarchy.LabelsAt(log.num_levels() - 1) !=
              *log.LabelsAt(log.num_levels() - 1)) {
        std::fprintf(stderr, "the received hierarchy differs\n");
        return 1;
      }
    }
    std::printf(
        "%-6s %5.1f MB on the wire (%.2f B/triplet); build %.3f s, serialize %.3f s, parse "
        "%.3f s; gRPC TCP loopback into HierarchyLog %.3f s = %.2f M triplets/s (server "
        "build+write %.3f s)\n",
        packed ? "packed" : "varint", wire_bytes / 1e6, wire_bytes / triplets, Median(build),
        Median(serialize), Median(parse), Median(e2e), triplets / Median(e2e) / 1e6,
        Median(server_side));
  }
  server->Shutdown();
  return 0;
}
