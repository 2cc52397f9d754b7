#include "client/client.h"

#include <zlib.h>

#include <algorithm>
#include <bit>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <fstream>
#include <mutex>
#include <optional>
#include <span>
#include <sstream>
#include <string>
#include <thread>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "core/base/renumber.h"
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
  // `absolute_levels`: level batches number levels as the job does (Watch), starting
  // after the snapshot's level; otherwise the snapshot is level 0 (Run).
  explicit HierarchyAssembler(JobResult& result, bool absolute_levels = false)
      : result_(result), absolute_levels_(absolute_levels) {}

  // The job's number of the last complete level this stream delivered, or -1 before its
  // snapshot is complete.
  int64_t last_complete_level() const {
    if (!started_) return -1;
    return static_cast<int64_t>(result_.first_level + stream_levels_) - 1;
  }
  bool started() const { return started_; }
  // Complete levels held, over every stream (ReceivedLevels).
  size_t levels_held() const { return hierarchy_started_ ? result_.hierarchy.num_levels() : 0; }

  // A new stream of the same job (another replica ran it again: ReceivedLevels): the levels
  // held are expected again first, checked against those held and skipped; the stream's own
  // state (a split level, a snapshot in pieces, its end) starts afresh.
  void BeginStream(bool absolute_levels) {
    DropPartialLevel();
    labels_.clear();
    started_ = false;
    done_ = false;
    stream_levels_ = 0;
    absolute_levels_ = absolute_levels;
    replay_levels_ = levels_held();
  }

  // How the last event Add took goes on to RunOptions::on_event: whole, not at all (it only
  // repeated levels held: a snapshot or levels a lost replica had sent), or trimmed to the
  // levels after those (trimmed()).
  enum class Forward { kWhole, kNone, kTrimmed };
  Forward forward() const { return forward_; }
  const v1::JobEvent& trimmed() const { return trimmed_; }

  // A stream broke: a level split across messages and not yet complete is dropped (the
  // resumed stream sends it again whole).
  void DropPartialLevel() {
    continuing_ = false;
    pending_element_.clear();
    pending_to_.clear();
    pending_from_.clear();
  }

  absl::Status Add(const v1::JobEvent& event) {
    forward_ = Forward::kWhole;
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
        if (stream_levels_ < replay_levels_) {
          return DifferentLevel(result_.first_level + stream_levels_,
                                absl::StrCat("the job ended after ", stream_levels_, " levels; ",
                                             replay_levels_, " were received before"));
        }
        result_.done = event.done();
        done_ = true;
        return absl::OkStatus();
      default:
        return absl::OkStatus();
    }
  }

  bool done() const { return done_; }

  // RunOptions::labels_for_clusters: follow the labels level by level and keep those of
  // the level ChooseLevel picks (the last with exactly `k` clusters, else the first with
  // fewer). Call before the first event.
  void TrackLabelsFor(uint32_t k) { track_k_ = k; }

  // At the end of the stream: the tracked level and labels into the result.
  void FinishTracking() {
    if (track_k_ == 0 || !started_) return;
    if (last_was_k_) {
      exact_level_ = result_.hierarchy.num_levels() - 1;
      exact_labels_ = std::move(current_);
    }
    if (exact_level_.has_value()) {
      result_.chosen_level = exact_level_;
      result_.chosen_labels = std::move(exact_labels_);
    } else if (fewer_level_.has_value()) {
      result_.chosen_level = fewer_level_;
      result_.chosen_labels = std::move(fewer_labels_);
    }
  }

 private:
  // After the hierarchy took level `hierarchy.num_levels() - 1` (`count` clusters, these
  // moves): the labels followed to it, and a copy kept where ChooseLevel could pick it.
  void Track(uint32_t count, std::span<const uint32_t> element, std::span<const uint32_t> to) {
    if (track_k_ == 0) return;
    const size_t level = result_.hierarchy.num_levels() - 1;
    const bool exact_seen = exact_level_.has_value() || last_was_k_;
    if (last_was_k_ && count != track_k_) {
      // A run of levels with exactly k clusters ended: its last level's labels.
      exact_level_ = level - 1;
      exact_labels_ = current_;
    }
    for (size_t i = 0; i < element.size(); ++i) current_[element[i]] = ClusterId(to[i]);
    last_was_k_ = count == track_k_;
    if (count < track_k_ && !exact_seen && !fewer_level_.has_value()) {
      fewer_level_ = level;
      fewer_labels_ = current_;
    }
  }

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
    if (replay_levels_ > 0) return RepeatSnapshot(snapshot);
    if (labels_.size() == snapshot.total_elements()) {
      started_ = true;
      hierarchy_started_ = true;
      stream_levels_ = 1;
      if (absolute_levels_) result_.first_level = snapshot.level();
      absl::Status status =
          result_.hierarchy.OnStart(labels_, snapshot.cluster_count(), snapshot.energy());
      if (status.ok() && track_k_ != 0) {
        current_ = std::move(labels_);
        last_was_k_ = snapshot.cluster_count() == track_k_;
        if (snapshot.cluster_count() < track_k_) {
          fewer_level_ = 0;
          fewer_labels_ = current_;
        }
      }
      std::vector<ClusterId>().swap(labels_);
      return status;
    }
    return absl::OkStatus();
  }

  // A snapshot piece of a stream that repeats the levels held (BeginStream): it must equal
  // the held start, label for label.
  absl::Status RepeatSnapshot(const v1::LevelSnapshot& snapshot) {
    forward_ = Forward::kNone;
    const HierarchyLog& held = result_.hierarchy;
    const std::span<const ClusterId> start = held.start_labels();
    if (snapshot.total_elements() != start.size() ||
        (absolute_levels_ && snapshot.level() != result_.first_level) ||
        !std::equal(labels_.begin() + snapshot.first_element(), labels_.end(),
                    start.begin() + snapshot.first_element())) {
      return DifferentLevel(result_.first_level, "its start labels differ");
    }
    if (labels_.size() < snapshot.total_elements()) return absl::OkStatus();
    if (snapshot.cluster_count() != held.cluster_count(0) || snapshot.energy() != held.energy(0)) {
      return DifferentLevel(result_.first_level,
                            CountAndEnergy(snapshot.cluster_count(), snapshot.energy(),
                                           held.cluster_count(0), held.energy(0)));
    }
    started_ = true;
    stream_levels_ = 1;
    std::vector<ClusterId>().swap(labels_);
    return absl::OkStatus();
  }

  // Energies to the last bit: two replicas may differ only there.
  static std::string CountAndEnergy(uint32_t count, double energy, uint32_t held_count,
                                    double held_energy) {
    return absl::StrFormat("it has %u clusters (energy %.17g), the level held %u (energy %.17g)",
                           count, energy, held_count, held_energy);
  }

  static absl::Status DifferentLevel(uint64_t level, const std::string& how) {
    return absl::DataLossError(
        absl::StrCat("the job was run again on another replica and its level ", level,
                     " differs from the one received before (", how,
                     "): the replicas do not compute the same levels (different builds, versions "
                     "or devices: a GPU replica's float order may differ from a CPU one's?)"));
  }

  absl::Status AddLevels(const v1::LevelBatch& batch) {
    if (!started_) return absl::DataLossError("levels arrived before the snapshot");
    const int count = batch.cluster_count_size();
    if (batch.energy_size() != count || batch.triplet_end_size() != count) {
      return absl::DataLossError("a level batch with arrays of different lengths");
    }
    const uint64_t expected = result_.first_level + stream_levels_;
    if (batch.first_level() != expected) {
      return absl::DataLossError(
          absl::StrCat("levels from ", batch.first_level(), " arrived, expected level ", expected));
    }
    std::span<const uint32_t> all_element(batch.element().data(), batch.element_size());
    std::span<const uint32_t> all_to(batch.to_cluster().data(), batch.to_cluster_size());
    std::span<const uint32_t> all_from(batch.from_cluster().data(), batch.from_cluster_size());
    if (!batch.packed_element().empty() || !batch.packed_to_cluster().empty() ||
        !batch.packed_from_cluster().empty()) {
      // JobSpec.packed_triplets: raw little-endian uint32, copied out to aligned arrays.
      if (!all_element.empty() || !all_to.empty() || !all_from.empty()) {
        return absl::DataLossError("a level batch with both packed and repeated triplets");
      }
      MLCLUST_RETURN_IF_ERROR(Unpack(batch.packed_element(), unpacked_element_));
      MLCLUST_RETURN_IF_ERROR(Unpack(batch.packed_to_cluster(), unpacked_to_));
      MLCLUST_RETURN_IF_ERROR(Unpack(batch.packed_from_cluster(), unpacked_from_));
      all_element = unpacked_element_;
      all_to = unpacked_to_;
      all_from = unpacked_from_;
    }
    if (all_to.size() != all_element.size() || all_from.size() != all_element.size()) {
      return absl::DataLossError("a level batch with triplet arrays of different lengths");
    }
    if (count == 0 && batch.last_level_continues()) {
      return absl::DataLossError("an empty level batch that says its last level continues");
    }
    // The leading entries that repeat levels held (each piece of a split level counts as
    // one entry) are not passed on to on_event.
    int repeated = 0;
    uint32_t begin = 0;
    for (int i = 0; i < count; ++i) {
      if (stream_levels_ < replay_levels_) repeated = i + 1;
      const uint32_t end = batch.triplet_end(i);
      if (end < begin || end > all_element.size()) {
        return absl::DataLossError("a level batch with triplet_end out of order");
      }
      const std::span<const uint32_t> element = all_element.subspan(begin, end - begin);
      const std::span<const uint32_t> to = all_to.subspan(begin, end - begin);
      const std::span<const uint32_t> from = all_from.subspan(begin, end - begin);
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
    if (repeated == count) {
      forward_ = Forward::kNone;
    } else if (repeated > 0) {
      forward_ = Forward::kTrimmed;
      TrimBatch(batch, repeated);
    }
    return absl::OkStatus();
  }

  // trimmed_: `batch` without its first `skip` entries (levels, or pieces of one).
  void TrimBatch(const v1::LevelBatch& batch, int skip) {
    trimmed_.Clear();
    v1::LevelBatch& out = *trimmed_.mutable_levels();
    const uint32_t skip_triplets = batch.triplet_end(skip - 1);
    out.set_first_level(batch.first_level() + skip);
    for (int i = skip; i < batch.cluster_count_size(); ++i) {
      out.add_cluster_count(batch.cluster_count(i));
      out.add_energy(batch.energy(i));
      out.add_triplet_end(batch.triplet_end(i) - skip_triplets);
      if (i < batch.source_level_size()) out.add_source_level(batch.source_level(i));
    }
    out.set_last_level_continues(batch.last_level_continues());
    const size_t skip_bytes = size_t{skip_triplets} * sizeof(uint32_t);
    if (!batch.packed_element().empty()) {
      out.set_packed_element(batch.packed_element().substr(skip_bytes));
      out.set_packed_to_cluster(batch.packed_to_cluster().substr(skip_bytes));
      out.set_packed_from_cluster(batch.packed_from_cluster().substr(skip_bytes));
    } else {
      out.mutable_element()->Add(batch.element().begin() + skip_triplets, batch.element().end());
      out.mutable_to_cluster()->Add(batch.to_cluster().begin() + skip_triplets,
                                    batch.to_cluster().end());
      out.mutable_from_cluster()->Add(batch.from_cluster().begin() + skip_triplets,
                                      batch.from_cluster().end());
    }
  }

  static absl::Status Unpack(const std::string& bytes, std::vector<uint32_t>& values) {
    static_assert(std::endian::native == std::endian::little,
                  "packed triplets are little-endian uint32");
    if (bytes.size() % sizeof(uint32_t) != 0) {
      return absl::DataLossError("a packed triplet array whose length is not a multiple of 4");
    }
    values.resize(bytes.size() / sizeof(uint32_t));
    if (!bytes.empty()) std::memcpy(values.data(), bytes.data(), bytes.size());
    return absl::OkStatus();
  }

  absl::Status ApplyLevel(uint32_t cluster_count, double energy, std::span<const uint32_t> element,
                          std::span<const uint32_t> to, std::span<const uint32_t> from) {
    if (stream_levels_ < replay_levels_) {
      // A level held already (ReceivedLevels): the same cluster count, energy and triplets,
      // or the replicas disagree; it is not applied again.
      const LevelMoves held = result_.hierarchy.level(stream_levels_);
      const uint64_t number = result_.first_level + stream_levels_;
      if (cluster_count != held.cluster_count || energy != held.energy) {
        return DifferentLevel(
            number, CountAndEnergy(cluster_count, energy, held.cluster_count, held.energy));
      }
      if (!std::ranges::equal(element, held.element) || !std::ranges::equal(to, held.to_cluster) ||
          !std::ranges::equal(from, held.from_cluster)) {
        return DifferentLevel(number,
                              absl::StrCat("its ", element.size(), " triplets differ from the ",
                                           held.element.size(), " held"));
      }
      ++stream_levels_;
      return absl::OkStatus();
    }
    LevelMoves level;
    level.cluster_count = cluster_count;
    level.energy = energy;
    level.element = element;
    level.to_cluster = to;
    level.from_cluster = from;
    if (absl::Status s = result_.hierarchy.OnLevel(level); !s.ok()) {
      return absl::DataLossError(s.message());
    }
    Track(cluster_count, element, to);
    ++stream_levels_;
    return absl::OkStatus();
  }

  JobResult& result_;
  bool absolute_levels_;
  std::vector<ClusterId> labels_;
  // Complete levels of this stream (the snapshot counts one), and the first this many of
  // them repeat levels held from an earlier stream (BeginStream).
  size_t stream_levels_ = 0;
  size_t replay_levels_ = 0;
  bool hierarchy_started_ = false;  // over every stream: the hierarchy has its level 0
  Forward forward_ = Forward::kWhole;
  v1::JobEvent trimmed_;
  // A level whose triplets arrive in several batches, joined here.
  bool continuing_ = false;
  uint32_t pending_cluster_count_ = 0;
  double pending_energy_ = 0;
  std::vector<uint32_t> pending_element_, pending_to_, pending_from_;
  std::vector<uint32_t> unpacked_element_, unpacked_to_, unpacked_from_;  // packed batches
  bool started_ = false;
  bool done_ = false;
  // TrackLabelsFor: the labels at the last level taken, the last level of a run with
  // exactly k clusters, and the first with fewer.
  uint32_t track_k_ = 0;
  std::vector<ClusterId> current_;
  bool last_was_k_ = false;
  std::optional<size_t> exact_level_, fewer_level_;
  std::vector<ClusterId> exact_labels_, fewer_labels_;
};

// The events of a call, read (and parsed) by a reader thread while the caller's thread
// rebuilds the levels: at most `capacity` wait in between, so a slow rebuild holds the
// stream back (gRPC's flow control) instead of memory growing.
class ReadAhead {
 public:
  explicit ReadAhead(size_t capacity) : capacity_(std::max<size_t>(1, capacity)) {}

  // The reader's side: false once the consumer stopped (Stop).
  bool Push(v1::JobEvent event) {
    std::unique_lock<std::mutex> lock(mutex_);
    room_.wait(lock, [&] { return stopped_ || events_.size() < capacity_; });
    if (stopped_) return false;
    events_.push_back(std::move(event));
    ready_.notify_one();
    return true;
  }
  // The stream ended (Read returned false).
  void End() {
    std::lock_guard<std::mutex> lock(mutex_);
    ended_ = true;
    ready_.notify_one();
  }
  // The consumer's side: false once the stream ended and every event was taken.
  bool Pop(v1::JobEvent& event) {
    std::unique_lock<std::mutex> lock(mutex_);
    ready_.wait(lock, [&] { return ended_ || !events_.empty(); });
    if (events_.empty()) return false;
    event = std::move(events_.front());
    events_.pop_front();
    room_.notify_one();
    return true;
  }
  // The consumer stops taking events (an inconsistent stream): the reader drops the rest.
  void Stop() {
    std::lock_guard<std::mutex> lock(mutex_);
    stopped_ = true;
    events_.clear();
    room_.notify_one();
  }

 private:
  const size_t capacity_;
  std::mutex mutex_;
  std::condition_variable ready_, room_;
  std::deque<v1::JobEvent> events_;
  bool ended_ = false;
  bool stopped_ = false;
};

// RunOptions/WatchOptions::on_event after the assembler took `event`: levels held from an
// earlier stream (ReceivedLevels) are not passed on again.
void PassOn(const HierarchyAssembler& assembler, const v1::JobEvent& event,
            const std::function<void(const v1::JobEvent&)>& on_event) {
  switch (assembler.forward()) {
    case HierarchyAssembler::Forward::kWhole:
      on_event(event);
      break;
    case HierarchyAssembler::Forward::kTrimmed: {
      v1::JobEvent trimmed = assembler.trimmed();
      trimmed.set_final(event.final());
      on_event(trimmed);
      break;
    }
    case HierarchyAssembler::Forward::kNone:
      break;
  }
}

}  // namespace

struct ReceivedLevels::State {
  JobResult result;
  HierarchyAssembler assembler{result};
  bool begun = false;      // a call used it
  bool saw_final = false;  // the last stream carried the job's final event
};

ReceivedLevels::ReceivedLevels() : state_(std::make_unique<State>()) {}
ReceivedLevels::~ReceivedLevels() = default;
size_t ReceivedLevels::levels() const { return state_->assembler.levels_held(); }
bool ReceivedLevels::saw_final() const { return state_->saw_final; }

std::shared_ptr<grpc::Channel> Connect(const std::string& address) {
  grpc::ChannelArguments arguments;
  arguments.SetMaxReceiveMessageSize(-1);
  return grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), arguments);
}

namespace {

// Sends `spec` (its input_bytes and input_crc32 set here) with the first chunk of `input`,
// then the rest. A failed write means the server has already answered (for example a full
// queue); its status comes from the stream's Finish.
void Upload(grpc::ClientReaderWriter<v1::RunRequest, v1::JobEvent>& stream, v1::JobSpec spec,
            std::string_view input, size_t chunk_bytes) {
  spec.set_input_bytes(input.size());
  spec.set_input_crc32(static_cast<uint32_t>(
      crc32_z(0, reinterpret_cast<const Bytef*>(input.data()), input.size())));
  const size_t chunk = std::max<size_t>(1, chunk_bytes);
  v1::RunRequest request;
  *request.mutable_spec() = std::move(spec);
  size_t offset = 0;
  do {
    const size_t n = std::min(chunk, input.size() - offset);
    request.set_chunk(input.data() + offset, n);
    offset += n;
    if (!stream.Write(request)) return;
    request.clear_spec();
  } while (offset < input.size());
  stream.WritesDone();
}

void SetDeadline(grpc::ClientContext& context, absl::Duration deadline) {
  if (deadline != absl::InfiniteDuration()) {
    context.set_deadline(absl::ToChronoTime(absl::Now() + deadline));
  }
}

absl::StatusOr<std::string> ReadFile(const std::string& path, const char* what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return absl::InvalidArgumentError(absl::StrCat(what, ": cannot read ", path));
  std::ostringstream bytes;
  bytes << in.rdbuf();
  return bytes.str();
}

}  // namespace

bool IsBrokenStream(const absl::Status& status) {
  return status.code() == absl::StatusCode::kUnavailable ||
         (status.code() == absl::StatusCode::kInternal &&
          absl::StrContains(status.message(), "RST_STREAM")) ||
         (status.code() == absl::StatusCode::kUnknown &&
          absl::StrContains(status.message(), "Stream removed"));
}

absl::StatusOr<std::shared_ptr<grpc::Channel>> Connect(const std::string& address,
                                                       const ConnectOptions& options) {
  grpc::ChannelArguments arguments;
  arguments.SetMaxReceiveMessageSize(-1);
  std::shared_ptr<grpc::ChannelCredentials> credentials;
  if (options.tls_ca_file.empty()) {
    if (!options.auth_token_file.empty()) {
      return absl::InvalidArgumentError(
          "--auth-token-file needs TLS (--tls-ca FILE): a bearer token is never sent in "
          "plaintext");
    }
    if (!options.tls_cert_file.empty() || !options.tls_key_file.empty()) {
      return absl::InvalidArgumentError("--tls-cert and --tls-key need --tls-ca");
    }
    credentials = grpc::InsecureChannelCredentials();
  } else {
    grpc::SslCredentialsOptions ssl;
    MLCLUST_ASSIGN_OR_RETURN(ssl.pem_root_certs, ReadFile(options.tls_ca_file, "--tls-ca"));
    if (!options.tls_cert_file.empty() || !options.tls_key_file.empty()) {
      if (options.tls_cert_file.empty() || options.tls_key_file.empty()) {
        return absl::InvalidArgumentError("--tls-cert and --tls-key go together");
      }
      MLCLUST_ASSIGN_OR_RETURN(ssl.pem_cert_chain, ReadFile(options.tls_cert_file, "--tls-cert"));
      MLCLUST_ASSIGN_OR_RETURN(ssl.pem_private_key, ReadFile(options.tls_key_file, "--tls-key"));
    }
    credentials = grpc::SslCredentials(ssl);
    if (!options.auth_token_file.empty()) {
      MLCLUST_ASSIGN_OR_RETURN(const std::string text,
                               ReadFile(options.auth_token_file, "--auth-token-file"));
      std::string token;
      for (absl::string_view line : absl::StrSplit(text, '\n')) {
        line = absl::StripAsciiWhitespace(line);
        if (line.empty() || line.front() == '#') continue;
        // The first word: a server's token file (token tenant) works here as well.
        token = std::string(line.substr(0, line.find_first_of(" \t")));
        break;
      }
      if (token.empty()) {
        return absl::InvalidArgumentError(
            absl::StrCat("--auth-token-file: ", options.auth_token_file, " holds no token"));
      }
      credentials =
          grpc::CompositeChannelCredentials(credentials, grpc::AccessTokenCredentials(token));
    }
  }
  return grpc::CreateCustomChannel(address, credentials, arguments);
}

absl::StatusOr<JobResult> RunJob(const std::shared_ptr<grpc::Channel>& channel, v1::JobSpec spec,
                                 std::string_view input, const RunOptions& options) {
  auto stub = v1::Clustering::NewStub(channel);
  grpc::ClientContext context;
  SetDeadline(context, options.deadline);
  std::unique_ptr<grpc::ClientReaderWriter<v1::RunRequest, v1::JobEvent>> stream =
      stub->Run(&context);
  spec.set_detach(false);
  // Raw uint32 triplets (issue 13); an older server ignores the flag and sends varints.
  spec.set_packed_triplets(options.packed_triplets);
  Upload(*stream, std::move(spec), input, options.chunk_bytes);

  // One stream's levels, or the job's over several streams (RunOptions::received).
  std::optional<ReceivedLevels> own;
  ReceivedLevels& received = options.received != nullptr ? *options.received : own.emplace();
  JobResult& result = received.state().result;
  HierarchyAssembler& assembler = received.state().assembler;
  if (!received.state().begun) assembler.TrackLabelsFor(options.labels_for_clusters);
  received.state().begun = true;
  received.state().saw_final = false;
  assembler.BeginStream(/*absolute_levels=*/false);
  absl::Status stream_status;
  auto take = [&](const v1::JobEvent& event) {
    received.state().saw_final = received.state().saw_final || event.final();
    if (stream_status.ok()) stream_status = assembler.Add(event);
    if (options.on_event) PassOn(assembler, event, options.on_event);
    return stream_status.ok();
  };
  if (options.read_ahead_events == 0) {
    v1::JobEvent event;
    while (stream->Read(&event)) {
      if (!take(event)) context.TryCancel();
    }
  } else {
    // Receiving overlaps the rebuild: a reader thread reads and parses the next events
    // while this thread applies the levels (and calls on_event).
    ReadAhead queue(options.read_ahead_events);
    std::thread reader([&] {
      v1::JobEvent event;
      while (stream->Read(&event)) {
        if (!queue.Push(std::move(event))) {
          context.TryCancel();  // the rest is drained and dropped
        }
      }
      queue.End();
    });
    v1::JobEvent event;
    while (queue.Pop(event)) {
      if (!take(event)) {
        queue.Stop();
        context.TryCancel();
        break;
      }
    }
    reader.join();
  }
  const grpc::Status status = stream->Finish();
  if (!stream_status.ok()) return stream_status;
  if (!status.ok()) return FromGrpc(status);
  if (!assembler.done()) return absl::DataLossError("the job ended without a done event");
  assembler.FinishTracking();
  return std::move(result);
}

absl::StatusOr<v1::Accepted> SubmitDetached(const std::shared_ptr<grpc::Channel>& channel,
                                            v1::JobSpec spec, std::string_view input,
                                            const RunOptions& options) {
  auto stub = v1::Clustering::NewStub(channel);
  grpc::ClientContext context;
  SetDeadline(context, options.deadline);
  std::unique_ptr<grpc::ClientReaderWriter<v1::RunRequest, v1::JobEvent>> stream =
      stub->Run(&context);
  spec.set_detach(true);
  Upload(*stream, std::move(spec), input, options.chunk_bytes);
  std::optional<v1::Accepted> accepted;
  v1::JobEvent event;
  while (stream->Read(&event)) {
    if (options.on_event) options.on_event(event);
    if (event.has_accepted()) accepted = event.accepted();
  }
  const grpc::Status status = stream->Finish();
  if (!status.ok()) return FromGrpc(status);
  if (!accepted.has_value() || !accepted->detached()) {
    return absl::DataLossError(
        "the server did not detach the job (an older server without JobSpec.detach?)");
  }
  return *accepted;
}

absl::StatusOr<JobResult> WatchJob(const std::shared_ptr<grpc::Channel>& channel,
                                   const std::string& job_id, const WatchOptions& options) {
  auto stub = v1::Clustering::NewStub(channel);
  const absl::Time deadline = options.deadline == absl::InfiniteDuration()
                                  ? absl::InfiniteFuture()
                                  : absl::Now() + options.deadline;
  std::optional<ReceivedLevels> own;
  ReceivedLevels& received = options.received != nullptr ? *options.received : own.emplace();
  JobResult& result = received.state().result;
  HierarchyAssembler* assembler = &received.state().assembler;
  received.state().begun = true;
  // A job's levels held from another replica's stream (the job submitted again) come
  // again first, from the same first level.
  const uint32_t from_level =
      assembler->levels_held() > 0 ? result.first_level : options.from_level;
  assembler->BeginStream(/*absolute_levels=*/true);
  int resumes = 0;
  while (true) {
    received.state().saw_final = false;
    grpc::ClientContext context;
    if (deadline != absl::InfiniteFuture()) context.set_deadline(absl::ToChronoTime(deadline));
    v1::WatchRequest request;
    request.set_job_id(job_id);
    if (assembler->started()) {
      // Resume where the stream stopped: no snapshot, the levels after the last complete one.
      request.set_from_level(static_cast<uint32_t>(assembler->last_complete_level()));
      request.set_resume(true);
    } else {
      request.set_from_level(from_level);
    }
    std::unique_ptr<grpc::ClientReader<v1::JobEvent>> stream = stub->Watch(&context, request);
    absl::Status stream_status;
    bool progressed = false;
    bool final_seen = false;  // the job's own end: its status is not a broken stream
    v1::JobEvent event;
    while (stream->Read(&event)) {
      progressed = true;
      final_seen = final_seen || event.final();
      received.state().saw_final = final_seen;
      if (stream_status.ok()) stream_status = assembler->Add(event);
      if (options.on_event) PassOn(*assembler, event, options.on_event);
      if (!stream_status.ok()) context.TryCancel();
    }
    const grpc::Status status = stream->Finish();
    if (!stream_status.ok()) return stream_status;
    if (status.ok()) {
      if (!assembler->done()) return absl::DataLossError("the watch ended without a done event");
      result.job_id = job_id;
      return std::move(result);
    }
    const absl::Status failed = FromGrpc(status);
    if (final_seen || !IsBrokenStream(failed) || absl::Now() + options.resume_delay >= deadline) {
      return failed;
    }
    if (progressed) resumes = 0;
    if (++resumes > options.max_resumes) return failed;
    if (options.on_resume) options.on_resume(failed);
    assembler->DropPartialLevel();
    if (!assembler->started()) {
      // The snapshot was cut short: start again from it.
      assembler->BeginStream(/*absolute_levels=*/true);
    }
    std::this_thread::sleep_for(absl::ToChronoNanoseconds(options.resume_delay));
  }
}

absl::StatusOr<std::string> CancelJob(const std::shared_ptr<grpc::Channel>& channel,
                                      const std::string& job_id, absl::Duration deadline) {
  auto stub = v1::Clustering::NewStub(channel);
  grpc::ClientContext context;
  SetDeadline(context, deadline);
  v1::CancelRequest request;
  request.set_job_id(job_id);
  v1::CancelReply reply;
  const grpc::Status status = stub->Cancel(&context, request, &reply);
  if (!status.ok()) return FromGrpc(status);
  return reply.state();
}

absl::StatusOr<v1::JobList> ListJobs(const std::shared_ptr<grpc::Channel>& channel,
                                     absl::Duration deadline) {
  auto stub = v1::Clustering::NewStub(channel);
  grpc::ClientContext context;
  SetDeadline(context, deadline);
  v1::JobList list;
  const grpc::Status status = stub->ListJobs(&context, v1::ListJobsRequest(), &list);
  if (!status.ok()) return FromGrpc(status);
  return list;
}

std::vector<uint32_t> CompactLabels(std::span<const ClusterId> labels) {
  return RenumberByFirstAppearance(labels).dense;
}

}  // namespace mlclust::client
