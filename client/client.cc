#include "client/client.h"

#include "absl/container/flat_hash_map.h"
#include "absl/strings/str_cat.h"
#include "core/base/status_macros.h"
#include "grpcpp/grpcpp.h"
#include "mlclust/v1/mlclust.grpc.pb.h"

namespace mlclust::client {
namespace {

absl::Status FromGrpc(const grpc::Status& status) {
  return absl::Status(static_cast<absl::StatusCode>(status.error_code()), status.error_message());
}

// Assembles the events of one job into a HierarchyLog, checking that the stream is
// consistent (the snapshot complete before any level, levels consecutive).
class HierarchyAssembler {
 public:
  explicit HierarchyAssembler(JobResult& result) : result_(result) {}

  absl::Status Add(const v1::JobEvent& event) {
    switch (event.event_case()) {
      case v1::JobEvent::kAccepted:
        result_.job_id = event.accepted().job_id();
        return absl::OkStatus();
      case v1::JobEvent::kSnapshot:
        return AddSnapshot(event.snapshot());
      case v1::JobEvent::kLevels:
        return AddLevels(event.levels());
      case v1::JobEvent::kPreview:
        result_.preview = event.preview();
        return absl::OkStatus();
      case v1::JobEvent::kDone:
        if (continuing_) return absl::DataLossError("the job ended inside a split level");
        result_.done = event.done();
        done_ = true;
        return absl::OkStatus();
      default:
        return absl::OkStatus();
    }
  }

  bool done() const { return done_; }

 private:
  absl::Status AddSnapshot(const v1::LevelSnapshot& snapshot) {
    if (started_) return absl::DataLossError("a snapshot after the hierarchy had started");
    if (snapshot.first_element() != labels_.size()) {
      return absl::DataLossError(absl::StrCat("snapshot piece starts at element ",
                                              snapshot.first_element(), ", expected ",
                                              labels_.size()));
    }
    for (uint32_t label : snapshot.labels()) labels_.push_back(ClusterId(label));
    if (labels_.size() > snapshot.total_elements()) {
      return absl::DataLossError("snapshot holds more labels than its total_elements");
    }
    if (labels_.size() == snapshot.total_elements()) {
      started_ = true;
      absl::Status status =
          result_.hierarchy.OnStart(labels_, snapshot.cluster_count(), snapshot.energy());
      std::vector<ClusterId>().swap(labels_);
      return status;
    }
    return absl::OkStatus();
  }

  absl::Status AddLevels(const v1::LevelBatch& batch) {
    if (!started_) return absl::DataLossError("levels arrived before the snapshot");
    const int count = batch.cluster_count_size();
    if (batch.energy_size() != count || batch.triplet_end_size() != count) {
      return absl::DataLossError("a level batch with arrays of different lengths");
    }
    if (batch.first_level() != result_.hierarchy.num_levels()) {
      return absl::DataLossError(absl::StrCat("levels from ", batch.first_level(),
                                              " arrived, expected level ",
                                              result_.hierarchy.num_levels()));
    }
    if (batch.to_cluster_size() != batch.element_size() ||
        batch.from_cluster_size() != batch.element_size()) {
      return absl::DataLossError("a level batch with triplet arrays of different lengths");
    }
    if (count == 0 && batch.last_level_continues()) {
      return absl::DataLossError("an empty level batch that says its last level continues");
    }
    uint32_t begin = 0;
    for (int i = 0; i < count; ++i) {
      const uint32_t end = batch.triplet_end(i);
      if (end < begin || end > static_cast<uint32_t>(batch.element_size())) {
        return absl::DataLossError("a level batch with triplet_end out of order");
      }
      const std::span<const uint32_t> element(batch.element().data() + begin, end - begin);
      const std::span<const uint32_t> to(batch.to_cluster().data() + begin, end - begin);
      const std::span<const uint32_t> from(batch.from_cluster().data() + begin, end - begin);
      begin = end;
      const bool continued = i == 0 && continuing_;
      const bool continues = i == count - 1 && batch.last_level_continues();
      if (continued) {
        if (batch.cluster_count(i) != pending_cluster_count_ ||
            batch.energy(i) != pending_energy_) {
          return absl::DataLossError(
              absl::StrCat("level ", batch.first_level(), " continued with another cluster count"));
        }
      } else {
        pending_element_.clear();
        pending_to_.clear();
        pending_from_.clear();
      }
      if (continued || continues) {
        // A level split across messages (LevelBatch.last_level_continues): its triplets
        // are joined before it is applied.
        pending_element_.insert(pending_element_.end(), element.begin(), element.end());
        pending_to_.insert(pending_to_.end(), to.begin(), to.end());
        pending_from_.insert(pending_from_.end(), from.begin(), from.end());
        pending_cluster_count_ = batch.cluster_count(i);
        pending_energy_ = batch.energy(i);
        continuing_ = continues;
        if (continues) break;
        MLCLUST_RETURN_IF_ERROR(ApplyLevel(batch.cluster_count(i), batch.energy(i),
                                           pending_element_, pending_to_, pending_from_));
        continue;
      }
      MLCLUST_RETURN_IF_ERROR(
          ApplyLevel(batch.cluster_count(i), batch.energy(i), element, to, from));
    }
    if (count > 0 && !batch.last_level_continues()) continuing_ = false;
    return absl::OkStatus();
  }

  absl::Status ApplyLevel(uint32_t cluster_count, double energy, std::span<const uint32_t> element,
                          std::span<const uint32_t> to, std::span<const uint32_t> from) {
    LevelMoves level;
    level.cluster_count = cluster_count;
    level.energy = energy;
    level.element = element;
    level.to_cluster = to;
    level.from_cluster = from;
    if (absl::Status s = result_.hierarchy.OnLevel(level); !s.ok()) {
      return absl::DataLossError(s.message());
    }
    return absl::OkStatus();
  }

  JobResult& result_;
  std::vector<ClusterId> labels_;
  // A level whose triplets arrive in several batches, joined here.
  bool continuing_ = false;
  uint32_t pending_cluster_count_ = 0;
  double pending_energy_ = 0;
  std::vector<uint32_t> pending_element_, pending_to_, pending_from_;
  bool started_ = false;
  bool done_ = false;
};

}  // namespace

std::shared_ptr<grpc::Channel> Connect(const std::string& address) {
  grpc::ChannelArguments arguments;
  arguments.SetMaxReceiveMessageSize(-1);
  return grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), arguments);
}

absl::StatusOr<JobResult> RunJob(const std::shared_ptr<grpc::Channel>& channel, v1::JobSpec spec,
                                 std::string_view input, const RunOptions& options) {
  auto stub = v1::Clustering::NewStub(channel);
  grpc::ClientContext context;
  if (options.deadline != absl::InfiniteDuration()) {
    context.set_deadline(absl::ToChronoTime(absl::Now() + options.deadline));
  }
  std::unique_ptr<grpc::ClientReaderWriter<v1::RunRequest, v1::JobEvent>> stream =
      stub->Run(&context);

  // Upload: the spec with the first chunk, then the rest. A failed write means the server
  // has already answered (for example a full queue); its status comes from Finish below.
  spec.set_input_bytes(input.size());
  const size_t chunk = std::max<size_t>(1, options.chunk_bytes);
  v1::RunRequest request;
  *request.mutable_spec() = spec;
  size_t offset = 0;
  bool writing = true;
  do {
    const size_t n = std::min(chunk, input.size() - offset);
    request.set_chunk(input.data() + offset, n);
    offset += n;
    if (!stream->Write(request)) {
      writing = false;
      break;
    }
    request.clear_spec();
  } while (offset < input.size());
  if (writing) stream->WritesDone();

  JobResult result;
  HierarchyAssembler assembler(result);
  absl::Status stream_status;
  v1::JobEvent event;
  while (stream->Read(&event)) {
    if (options.on_event) options.on_event(event);
    if (stream_status.ok()) stream_status = assembler.Add(event);
    if (!stream_status.ok()) context.TryCancel();
  }
  const grpc::Status status = stream->Finish();
  if (!stream_status.ok()) return stream_status;
  if (!status.ok()) return FromGrpc(status);
  if (!assembler.done()) return absl::DataLossError("the job ended without a done event");
  return result;
}

std::vector<uint32_t> CompactLabels(std::span<const ClusterId> labels) {
  absl::flat_hash_map<uint32_t, uint32_t> compact;
  std::vector<uint32_t> out(labels.size());
  for (size_t i = 0; i < labels.size(); ++i) {
    auto [it, inserted] =
        compact.try_emplace(labels[i].value(), static_cast<uint32_t>(compact.size()));
    out[i] = it->second;
  }
  return out;
}

}  // namespace mlclust::client
