#include "server/result_store.h"

#include <algorithm>
#include <utility>

#include "absl/strings/str_cat.h"
#include "google/protobuf/io/coded_stream.h"

namespace mlclust::server {
namespace {

using ::google::protobuf::io::CodedOutputStream;

// Bytes a piece may take before its fields' tags and length prefixes.
constexpr size_t kPieceOverhead = 256;

size_t Varint(uint32_t value) { return CodedOutputStream::VarintSize32(value); }

// A LevelBatch cut into pieces of at most `budget` serialized bytes: levels whole where
// they fit, a level bigger than the rest of a piece continued in the next piece (the
// piece it starts in has last_level_continues set; the next starts at the same level).
// Packed batches (JobSpec.packed_triplets) are cut the same way and stay packed.
std::vector<v1::JobEvent> SplitLevelBatch(const v1::LevelBatch& batch, size_t budget) {
  std::vector<v1::JobEvent> pieces;
  v1::LevelBatch* piece = nullptr;
  size_t piece_bytes = 0;
  const bool packed = !batch.packed_element().empty() || !batch.packed_to_cluster().empty() ||
                      !batch.packed_from_cluster().empty();
  uint32_t packed_triplets = 0;  // in the current piece, packed only
  auto start_piece = [&](uint32_t first_level) {
    piece = pieces.emplace_back().mutable_levels();
    piece->set_first_level(first_level);
    piece_bytes = kPieceOverhead;
    packed_triplets = 0;
  };
  const bool has_source = batch.source_level_size() == batch.cluster_count_size();
  uint32_t begin = 0;
  for (int i = 0; i < batch.cluster_count_size(); ++i) {
    const uint32_t end = batch.triplet_end(i);
    const uint32_t level = batch.first_level() + static_cast<uint32_t>(i);
    // cluster_count, energy (8 bytes), triplet_end (at most 5) and source_level.
    const size_t header_bytes =
        Varint(batch.cluster_count(i)) + 8 + 5 + (has_source ? Varint(batch.source_level(i)) : 0);
    auto triplet_bytes = [&](uint32_t t) {
      return Varint(batch.element(t)) + Varint(batch.to_cluster(t)) + Varint(batch.from_cluster(t));
    };
    uint32_t t = begin;
    if (piece == nullptr ||
        (piece->cluster_count_size() > 0 &&
         piece_bytes + header_bytes + (t < end ? (packed ? 12 : triplet_bytes(t)) : 0) > budget)) {
      start_piece(level);
    }
    while (true) {
      piece->add_cluster_count(batch.cluster_count(i));
      piece->add_energy(batch.energy(i));
      if (has_source) piece->add_source_level(batch.source_level(i));
      piece_bytes += header_bytes;
      if (packed) {
        // JobSpec.packed_triplets: 12 bytes a triplet, copied in ranges.
        const size_t room = budget > piece_bytes ? (budget - piece_bytes) / 12 : 0;
        const uint32_t take = static_cast<uint32_t>(
            std::min<size_t>(end - t, std::max<size_t>(room, packed_triplets == 0 ? 1 : 0)));
        for (auto [from, to] :
             {std::pair{&batch.packed_element(), piece->mutable_packed_element()},
              std::pair{&batch.packed_to_cluster(), piece->mutable_packed_to_cluster()},
              std::pair{&batch.packed_from_cluster(), piece->mutable_packed_from_cluster()}}) {
          to->append(*from, size_t{t} * 4, size_t{take} * 4);
        }
        t += take;
        packed_triplets += take;
        piece_bytes += size_t{take} * 12;
        piece->add_triplet_end(packed_triplets);
        if (t == end) break;
        piece->set_last_level_continues(true);
        start_piece(level);
        continue;
      }
      for (; t < end; ++t) {
        const size_t bytes = triplet_bytes(t);
        // Every piece takes at least one triplet, so the split always progresses.
        if (piece_bytes + bytes > budget && piece->element_size() > 0) break;
        piece->add_element(batch.element(t));
        piece->add_to_cluster(batch.to_cluster(t));
        piece->add_from_cluster(batch.from_cluster(t));
        piece_bytes += bytes;
      }
      piece->add_triplet_end(static_cast<uint32_t>(piece->element_size()));
      if (t == end) break;
      piece->set_last_level_continues(true);
      start_piece(level);
    }
    begin = end;
  }
  return pieces;
}

std::vector<v1::JobEvent> SplitSnapshot(const v1::LevelSnapshot& snapshot, size_t budget) {
  std::vector<v1::JobEvent> pieces;
  const int n = snapshot.labels_size();
  int first = 0;
  while (first < n) {
    v1::LevelSnapshot* piece = pieces.emplace_back().mutable_snapshot();
    piece->set_level(snapshot.level());
    piece->set_cluster_count(snapshot.cluster_count());
    piece->set_energy(snapshot.energy());
    piece->set_first_element(snapshot.first_element() + static_cast<uint32_t>(first));
    piece->set_total_elements(snapshot.total_elements());
    size_t bytes = kPieceOverhead;
    int end = first;
    while (end < n && (end == first || bytes + Varint(snapshot.labels(end)) <= budget)) {
      bytes += Varint(snapshot.labels(end));
      ++end;
    }
    piece->mutable_labels()->Add(snapshot.labels().begin() + first,
                                 snapshot.labels().begin() + end);
    first = end;
  }
  return pieces;
}

}  // namespace

std::vector<v1::JobEvent> SplitLargeEvent(v1::JobEvent event, size_t max_bytes) {
  std::vector<v1::JobEvent> pieces;
  const bool splittable =
      (event.has_levels() &&
       event.levels().triplet_end_size() == event.levels().cluster_count_size() &&
       !event.levels().last_level_continues()) ||
      (event.has_snapshot() && event.snapshot().labels_size() > 1);
  if (!splittable || event.ByteSizeLong() <= max_bytes) {
    pieces.push_back(std::move(event));
    return pieces;
  }
  const size_t budget = std::max<size_t>(max_bytes, 2 * kPieceOverhead);
  pieces = event.has_levels() ? SplitLevelBatch(event.levels(), budget)
                              : SplitSnapshot(event.snapshot(), budget);
  for (v1::JobEvent& piece : pieces) piece.set_final(event.final());
  return pieces;
}

ResultStore::ResultStore(EventWriter* writer, MemoryBudget* server_budget,
                         ResultStoreOptions options)
    : options_(std::move(options)), server_budget_(server_budget), writer_(writer) {}

ResultStore::~ResultStore() { DropHeld(); }

bool ResultStore::Emit(v1::JobEvent event) {
  if (cancelled()) return false;
  std::vector<v1::JobEvent> pieces = SplitLargeEvent(std::move(event), options_.max_event_bytes);
  std::unique_lock<std::mutex> lock(mutex_);
  if (cancelled() || finished_ || finish_requested_) return false;
  for (v1::JobEvent& piece : pieces) {
    const uint64_t bytes = piece.SpaceUsedLong();
    if (held_bytes_ + bytes > options_.job_budget_bytes) {
      CutOff(absl::StrCat("the client read too slowly: ", (held_bytes_ + bytes) >> 20,
                          " MiB of events waited unread, over the job's budget of ",
                          options_.job_budget_bytes >> 20, " MiB"),
             lock);
      return false;
    }
    if (!server_budget_->TryReserve(bytes)) {
      CutOff(absl::StrCat("the server's memory for unread events (", server_budget_->limit() >> 20,
                          " MiB) is full and this job's client read too slowly (",
                          (held_bytes_ + bytes) >> 20, " MiB waiting)"),
             lock);
      return false;
    }
    held_bytes_ += bytes;
    held_.push_back({std::move(piece), bytes});
  }
  Pump(lock);
  return true;
}

void ResultStore::Finish(v1::JobEvent final_event, const grpc::Status& status) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (finish_requested_ || finished_) return;
  final_event.set_final(true);
  // The final event is small (Done or Failed) and always kept: it is not counted against
  // the budgets, so a job at its budget can still say how it ended.
  held_.push_back({std::move(final_event), 0});
  finish_requested_ = true;
  finish_status_ = status;
  Pump(lock);
}

void ResultStore::HoldFailed(const grpc::Status& status) {
  v1::JobEvent failed;
  failed.mutable_failed()->set_code(status.error_code());
  failed.mutable_failed()->set_message(status.error_message());
  failed.set_final(true);
  held_.push_back({std::move(failed), 0});
  finish_requested_ = true;
  finish_status_ = status;
}

void ResultStore::Abort(const grpc::Status& status) {
  cancelled_ = true;  // an explicit cancel reaches a released job too
  std::unique_lock<std::mutex> lock(mutex_);
  if (finished_) return;
  DropHeld();
  if (!finish_requested_) {
    HoldFailed(status);
  }
  Pump(lock);
}

void ResultStore::KeepJobOnCutOff(std::string job_id) {
  std::lock_guard<std::mutex> lock(mutex_);
  keep_job_id_ = std::move(job_id);
}

void ResultStore::CancelJobLocked() {
  if (!released()) cancelled_ = true;
}

void ResultStore::FlushForShutdown(const grpc::Status& status) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (finished_ || client_gone_ || writer_ == nullptr) return;
  size_t unread = 0;
  for (const Held& held : held_) unread += held.event.final() ? 0 : 1;
  if (unread == 0) return;
  DropHeld();
  HoldFailed(grpc::Status(status.error_code(),
                          absl::StrCat(status.error_message(), " (", unread,
                                       " events the client had not read were dropped)")));
  Pump(lock);
}

void ResultStore::CutOff(const std::string& why, std::unique_lock<std::mutex>& lock) {
  grpc::Status status;
  if (!keep_job_id_.empty()) {
    // The job's record keeps its levels: the job runs on for Watch.
    released_.store(true, std::memory_order_release);
    status = grpc::Status(
        grpc::StatusCode::RESOURCE_EXHAUSTED,
        absl::StrCat(why,
                     "; this call was cut off, but the job runs on and keeps its levels: "
                     "read them with `mlclust watch ",
                     keep_job_id_, "` (Watch, from any level)"));
  } else {
    cancelled_ = true;
    status = grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                          absl::StrCat(why, "; the job was cancelled"));
  }
  DropHeld();
  HoldFailed(status);
  // The write in flight (the one the client stopped reading) ends when the client reads
  // again or goes away; then the Failed event and the status follow.
  std::function<void(const grpc::Status&)> on_cut_off = options_.on_cut_off;
  Pump(lock);
  if (on_cut_off) on_cut_off(status);
}

void ResultStore::DropHeld() {
  for (const Held& held : held_) server_budget_->Release(held.bytes);
  held_.clear();
  held_bytes_ = 0;
}

void ResultStore::OnWriteDone(bool ok) {
  std::unique_lock<std::mutex> lock(mutex_);
  write_in_flight_ = false;
  if (!ok) {  // the client is gone
    client_gone_ = true;
    CancelJobLocked();
  }
  Pump(lock);
}

void ResultStore::OnCancel() {
  std::unique_lock<std::mutex> lock(mutex_);
  client_gone_ = true;
  CancelJobLocked();
  Pump(lock);
}

void ResultStore::Detach() {
  std::lock_guard<std::mutex> lock(mutex_);
  writer_ = nullptr;
  CancelJobLocked();
  DropHeld();
}

uint64_t ResultStore::held_bytes() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return held_bytes_;
}

void ResultStore::Pump(std::unique_lock<std::mutex>& lock) {
  if (write_in_flight_ || finished_ || writer_ == nullptr) {
    lock.unlock();
    return;
  }
  EventWriter* writer = writer_;
  // After a cut-off or an abort (job cancelled, finish requested) the final Failed event
  // is still written; once the client is gone nothing is.
  if (!held_.empty() && !client_gone_) {
    Held next = std::move(held_.front());
    held_.pop_front();
    held_bytes_ -= next.bytes;
    server_budget_->Release(next.bytes);
    in_flight_ = std::move(next.event);
    write_in_flight_ = true;
    if (options_.bytes_written != nullptr) *options_.bytes_written += in_flight_.ByteSizeLong();
    lock.unlock();
    writer->StartWrite(&in_flight_);
    return;
  }
  if (finish_requested_ || client_gone_) {
    finished_ = true;
    const grpc::Status status =
        finish_requested_ ? finish_status_ : grpc::Status(grpc::StatusCode::CANCELLED, "cancelled");
    DropHeld();
    lock.unlock();
    writer->Finish(status);
    return;
  }
  lock.unlock();
}

}  // namespace mlclust::server
