#include "server/job_record.h"

#include <algorithm>
#include <bit>
#include <cstring>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"

namespace mlclust::server {
namespace {

// Bytes of a LevelBatch piece before its triplets, and the most a triplet takes (three
// varints of at most 5 bytes).
constexpr size_t kBatchOverhead = 1024;
constexpr size_t kTripletBytes = 15;
constexpr int kMaxLevelsPerBatch = 16384;

std::string Timestamp(absl::Time time) {
  return absl::FormatTime("%Y-%m-%dT%H:%M:%SZ", time, absl::UTCTimeZone());
}

bool IsPacked(const v1::LevelBatch& batch) {
  return !batch.packed_element().empty() || !batch.packed_to_cluster().empty() ||
         !batch.packed_from_cluster().empty();
}

// Appends a packed array (raw little-endian uint32) to `values`; false for a length that is
// not a multiple of 4.
bool AppendPacked(const std::string& bytes, std::vector<uint32_t>& values) {
  static_assert(std::endian::native == std::endian::little,
                "packed triplets are little-endian uint32");
  if (bytes.size() % sizeof(uint32_t) != 0) return false;
  const size_t old_size = values.size();
  values.resize(old_size + bytes.size() / sizeof(uint32_t));
  if (!bytes.empty()) std::memcpy(values.data() + old_size, bytes.data(), bytes.size());
  return true;
}

v1::JobEvent FailedEvent(const grpc::Status& status) {
  v1::JobEvent event;
  event.mutable_failed()->set_code(status.error_code());
  event.mutable_failed()->set_message(status.error_message());
  return event;
}

}  // namespace

const char* JobStateName(JobState state) {
  switch (state) {
    case JobState::kQueued:
      return "queued";
    case JobState::kRunning:
      return "running";
    case JobState::kSucceeded:
      return "succeeded";
    case JobState::kFailed:
      return "failed";
    case JobState::kCancelled:
      return "cancelled";
  }
  return "unknown";
}

JobRecord::JobRecord(JobRegistry* registry, std::string id, std::string tenant, v1::JobSpec spec,
                     bool detached, size_t max_event_bytes)
    : registry_(registry),
      id_(std::move(id)),
      tenant_(std::move(tenant)),
      spec_(std::move(spec)),
      detached_(detached),
      max_event_bytes_(std::max<size_t>(max_event_bytes, 4 * kBatchOverhead)),
      accepted_at_(absl::Now()) {}

JobRecord::~JobRecord() {
  const uint64_t bytes = kept_bytes_.exchange(0);
  if (bytes > 0) registry_->ReleaseKept(bytes);
}

uint64_t JobRecord::BytesOf(const v1::JobEvent& event) {
  if (event.has_snapshot()) return uint64_t{4} * event.snapshot().labels_size();
  if (event.has_levels()) {
    const v1::LevelBatch& batch = event.levels();
    // 12 bytes per triplet: three repeated uint32, or three packed arrays of 4 bytes each.
    const uint64_t triplets = IsPacked(batch) ? batch.packed_element().size() / 4
                                              : static_cast<uint64_t>(batch.element_size());
    return uint64_t{12} * triplets + uint64_t{sizeof(Level)} * batch.cluster_count_size();
  }
  return 0;
}

JobRecord::Stored JobRecord::Store(const v1::JobEvent& event) {
  const uint64_t bytes = BytesOf(event);
  if (bytes > 0) {
    // Closed records reserve nothing (a reservation may drop other jobs' levels).
    std::lock_guard<std::mutex> lock(mutex_);
    if (final_set_ || cancelled() || !dropped_reason_.empty()) return Stored::kClosed;
  }
  if (bytes > 0 && !registry_->ReserveKept(bytes, this)) return Stored::kNoRoom;
  std::unique_lock<std::mutex> lock(mutex_);
  if (final_set_ || cancelled() || !dropped_reason_.empty()) {
    lock.unlock();
    registry_->ReleaseKept(bytes);
    return Stored::kClosed;
  }
  if (!StoreLocked(event)) {
    lock.unlock();
    registry_->ReleaseKept(bytes);
    return Stored::kInconsistent;
  }
  kept_bytes_ += bytes;
  WakeAll(lock);
  return Stored::kStored;
}

bool JobRecord::Emit(v1::JobEvent event) {
  if (cancelled()) return false;
  switch (Store(event)) {
    case Stored::kStored:
      return true;
    case Stored::kClosed:
      return false;
    case Stored::kNoRoom:
      Abort(grpc::Status(
          grpc::StatusCode::RESOURCE_EXHAUSTED,
          absl::StrCat("the job's levels do not fit the server's memory for kept results (",
                       registry_->kept_limit() >> 20, " MiB, ", registry_->kept_bytes() >> 20,
                       " MiB in use by running jobs); the job was cancelled")));
      return false;
    case Stored::kInconsistent:
      Abort(grpc::Status(grpc::StatusCode::INTERNAL,
                         "the job produced an inconsistent stream of levels"));
      return false;
  }
  return false;
}

void JobRecord::Keep(const v1::JobEvent& event) {
  std::string reason;
  switch (Store(event)) {
    case Stored::kStored:
    case Stored::kClosed:
      return;
    case Stored::kNoRoom:
      reason = absl::StrCat(
          "its levels were not kept: they did not fit the server's memory for "
          "kept results (",
          registry_->kept_limit() >> 20, " MiB); the call that submitted it received them");
      break;
    case Stored::kInconsistent:
      reason = "its levels were not kept: the job produced an inconsistent stream of levels";
      break;
  }
  registry_->ReleaseKept(DropLevels(reason));
}

bool JobRecord::StoreLocked(const v1::JobEvent& event) {
  if (event.has_progress()) {
    progress_ = event.progress();
    ++progress_seq_;
    return true;
  }
  if (event.has_snapshot()) {
    const v1::LevelSnapshot& snapshot = event.snapshot();
    if (snapshot_complete_ || snapshot.first_element() != snapshot_labels_.size()) return false;
    if (snapshot_labels_.empty()) {
      total_elements_ = snapshot.total_elements();
      snapshot_labels_.reserve(total_elements_);
    }
    snapshot_labels_.insert(snapshot_labels_.end(), snapshot.labels().begin(),
                            snapshot.labels().end());
    if (snapshot_labels_.size() > total_elements_) return false;
    if (snapshot_labels_.size() == total_elements_) {
      snapshot_complete_ = true;
      snapshot_cluster_count_ = snapshot.cluster_count();
      snapshot_energy_ = snapshot.energy();
      snapshot_source_level_ = snapshot.level();
      levels_total_ = 1;
    }
    return true;
  }
  if (event.has_levels()) {
    const v1::LevelBatch& batch = event.levels();
    const int count = batch.cluster_count_size();
    if (!snapshot_complete_ || batch.triplet_end_size() != count || batch.energy_size() != count ||
        batch.to_cluster_size() != batch.element_size() ||
        batch.from_cluster_size() != batch.element_size()) {
      return false;
    }
    const bool has_source = batch.source_level_size() == count;
    const uint64_t base = element_.size();
    if (IsPacked(batch)) {
      // JobSpec.packed_triplets (an attached job's copy): raw little-endian uint32.
      if (batch.element_size() != 0 || batch.to_cluster_size() != 0 ||
          batch.from_cluster_size() != 0 ||
          batch.packed_to_cluster().size() != batch.packed_element().size() ||
          batch.packed_from_cluster().size() != batch.packed_element().size() ||
          !AppendPacked(batch.packed_element(), element_) ||
          !AppendPacked(batch.packed_to_cluster(), to_cluster_) ||
          !AppendPacked(batch.packed_from_cluster(), from_cluster_)) {
        return false;
      }
    } else {
      element_.insert(element_.end(), batch.element().begin(), batch.element().end());
      to_cluster_.insert(to_cluster_.end(), batch.to_cluster().begin(), batch.to_cluster().end());
      from_cluster_.insert(from_cluster_.end(), batch.from_cluster().begin(),
                           batch.from_cluster().end());
    }
    for (int i = 0; i < count; ++i) {
      const uint64_t end = base + batch.triplet_end(i);
      if (end > element_.size()) return false;
      if (i == 0 && last_level_open_) {
        levels_.back().triplet_end = end;  // the rest of a split level
      } else {
        levels_.push_back(
            {batch.energy(i), end, batch.cluster_count(i), has_source ? batch.source_level(i) : 0});
      }
    }
    if (count > 0) last_level_open_ = batch.last_level_continues();
    levels_total_ = 1 + levels_.size() - (last_level_open_ ? 1 : 0);
    triplets_total_ = element_.size();
    return true;
  }
  return true;  // Accepted and others: nothing to keep
}

void JobRecord::Finish(v1::JobEvent final_event, const grpc::Status& status) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (final_set_) return;
  EndLocked(std::move(final_event), status);
  WakeAll(lock);
}

void JobRecord::Abort(const grpc::Status& status) {
  cancelled_ = true;
  std::unique_lock<std::mutex> lock(mutex_);
  if (final_set_) return;
  EndLocked(FailedEvent(status), status);
  WakeAll(lock);
}

void JobRecord::MarkRunning() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (final_set_) return;
  state_ = JobState::kRunning;
  started_at_ = absl::Now();
}

void JobRecord::MarkEnded(const grpc::Status& status, const v1::Done* done) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (final_set_) return;
  v1::JobEvent final_event;
  if (status.ok() && done != nullptr) {
    *final_event.mutable_done() = *done;
  } else {
    final_event = FailedEvent(status);
  }
  EndLocked(std::move(final_event), status);
  WakeAll(lock);
}

void JobRecord::EndLocked(v1::JobEvent final_event, const grpc::Status& status) {
  if (final_event.has_done() && !dropped_reason_.empty()) {
    // Levels not kept (an attached job's that did not fit): the counts from the job's Done.
    levels_total_ = final_event.done().levels();
    triplets_total_ = final_event.done().triplets();
  }
  final_event.set_final(true);
  final_event_ = std::move(final_event);
  final_set_ = true;
  status_ = status;
  state_ = status.ok()                                          ? JobState::kSucceeded
           : status.error_code() == grpc::StatusCode::CANCELLED ? JobState::kCancelled
                                                                : JobState::kFailed;
  ended_at_ = absl::Now();
  if (started_at_ == absl::InfinitePast()) started_at_ = ended_at_;
  ended_.store(true, std::memory_order_release);
}

JobState JobRecord::state() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return state_;
}

absl::Time JobRecord::ended_at() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return ended_at_;
}

v1::JobSummary JobRecord::Summary(absl::Time now, absl::Duration retention) const {
  std::lock_guard<std::mutex> lock(mutex_);
  v1::JobSummary summary;
  summary.set_job_id(id_);
  summary.set_state(JobStateName(state_));
  summary.set_algorithm(spec_.algorithm());
  summary.set_input_kind(spec_.input_kind());
  summary.set_input_bytes(spec_.input_bytes());
  summary.set_label(spec_.label());
  summary.set_detached(detached_);
  summary.set_levels(static_cast<uint32_t>(levels_total_));
  summary.set_triplets(triplets_total_);
  const absl::Time started = state_ == JobState::kQueued ? now : started_at_;
  summary.set_seconds_queued(absl::ToDoubleSeconds(started - accepted_at_));
  if (state_ != JobState::kQueued) {
    summary.set_seconds_running(
        absl::ToDoubleSeconds((final_set_ ? ended_at_ : now) - started_at_));
  }
  if (final_set_) {
    summary.set_code(status_.error_code());
    summary.set_message(status_.error_message());
    summary.set_expires_in_seconds(
        std::max(0.0, absl::ToDoubleSeconds(ended_at_ + retention - now)));
  }
  summary.set_kept_bytes(kept_bytes_.load(std::memory_order_relaxed));
  summary.set_tenant(tenant_);
  return summary;
}

uint64_t JobRecord::DropLevels(const std::string& reason) {
  std::unique_lock<std::mutex> lock(mutex_);
  dropped_reason_ = reason;
  std::vector<uint32_t>().swap(snapshot_labels_);
  std::vector<Level>().swap(levels_);
  std::vector<uint32_t>().swap(element_);
  std::vector<uint32_t>().swap(to_cluster_);
  std::vector<uint32_t>().swap(from_cluster_);
  level_labels_.clear();
  snapshot_complete_ = false;
  const uint64_t bytes = kept_bytes_.exchange(0);
  WakeAll(lock);
  return bytes;
}

void JobRecord::WakeAll(std::unique_lock<std::mutex>& lock) {
  std::vector<std::weak_ptr<RecordWaiter>> waiters;
  waiters.swap(waiters_);
  lock.unlock();
  for (const std::weak_ptr<RecordWaiter>& weak : waiters) {
    if (std::shared_ptr<RecordWaiter> waiter = weak.lock()) waiter->Wake();
  }
}

uint32_t JobRecord::ReadableLevelsLocked() const {
  if (!snapshot_complete_) return 0;
  return static_cast<uint32_t>(1 + levels_.size() - (last_level_open_ ? 1 : 0));
}

void JobRecord::BuildSnapshotLocked(WatchCursor& cursor) const {
  cursor.labels.reset();
  if (cursor.from_level > 0) {
    // One copy per level however many watchers start there (issue 24: a thousand
    // watchers each held their own).
    std::weak_ptr<const std::vector<uint32_t>>& cached = level_labels_[cursor.from_level];
    cursor.labels = cached.lock();
    if (cursor.labels == nullptr) {
      auto labels = std::make_shared<std::vector<uint32_t>>(snapshot_labels_);
      const uint64_t end = levels_[cursor.from_level - 1].triplet_end;
      for (uint64_t t = 0; t < end; ++t) (*labels)[element_[t]] = to_cluster_[t];
      cursor.labels = labels;
      cached = labels;
    }
    std::erase_if(level_labels_, [](const auto& entry) { return entry.second.expired(); });
  }
  cursor.snapshot_built = true;
  cursor.snapshot_sent = 0;
  cursor.next_level = cursor.from_level + 1;
  cursor.next_triplet = 0;
}

WatchCursor WatchCursorFor(uint32_t from_level, bool resume) {
  WatchCursor cursor;
  cursor.from_level = from_level;
  cursor.resume = resume;
  if (resume) {
    cursor.phase = WatchCursor::Phase::kLevels;
    cursor.next_level = from_level == UINT32_MAX ? UINT32_MAX : from_level + 1;
  }
  return cursor;
}

void JobRecord::FillLevelBatchLocked(WatchCursor& cursor, v1::LevelBatch& batch) const {
  const uint32_t readable = ReadableLevelsLocked();
  const uint64_t budget =
      std::max<uint64_t>(1, (max_event_bytes_ - kBatchOverhead) / kTripletBytes);
  uint64_t used = 0;
  batch.set_first_level(cursor.next_level);
  while (cursor.next_level < readable && batch.cluster_count_size() < kMaxLevelsPerBatch) {
    const Level& level = levels_[cursor.next_level - 1];
    const uint64_t level_begin =
        cursor.next_level == 1 ? 0 : levels_[cursor.next_level - 2].triplet_end;
    const uint64_t begin = level_begin + cursor.next_triplet;
    const uint64_t remaining = level.triplet_end - begin;
    const uint64_t room = budget > used + 2 ? budget - used - 2 : 0;
    uint64_t take = remaining;
    if (remaining > room) {
      if (batch.cluster_count_size() > 0) break;  // the level starts in the next batch
      take = std::max<uint64_t>(1, room);
    }
    batch.add_cluster_count(level.cluster_count);
    batch.add_energy(level.energy);
    batch.add_source_level(level.source_level);
    batch.mutable_element()->Add(element_.begin() + begin, element_.begin() + begin + take);
    batch.mutable_to_cluster()->Add(to_cluster_.begin() + begin,
                                    to_cluster_.begin() + begin + take);
    batch.mutable_from_cluster()->Add(from_cluster_.begin() + begin,
                                      from_cluster_.begin() + begin + take);
    batch.add_triplet_end(static_cast<uint32_t>(batch.element_size()));
    used += take + 2;
    if (take < remaining) {
      batch.set_last_level_continues(true);
      cursor.next_triplet += take;
      break;
    }
    ++cursor.next_level;
    cursor.next_triplet = 0;
  }
}

JobRecord::Next JobRecord::NextEvent(WatchCursor& cursor, v1::JobEvent& event, grpc::Status& status,
                                     const std::shared_ptr<RecordWaiter>& waiter) {
  std::lock_guard<std::mutex> lock(mutex_);
  event.Clear();
  if (!dropped_reason_.empty()) {
    cursor.phase = WatchCursor::Phase::kEnded;
    status =
        grpc::Status(grpc::StatusCode::NOT_FOUND, absl::StrCat("job ", id_, ": ", dropped_reason_));
    return Next::kEnd;
  }
  auto wait = [&] {
    if (progress_seq_ > cursor.progress_seen) {
      cursor.progress_seen = progress_seq_;
      *event.mutable_progress() = progress_;
      return Next::kEvent;
    }
    waiters_.push_back(waiter);
    return Next::kWait;
  };
  while (true) {
    switch (cursor.phase) {
      case WatchCursor::Phase::kHeader: {
        v1::Accepted* accepted = event.mutable_accepted();
        *accepted = accepted_;
        accepted->set_queue_position(0);
        accepted->set_job_id(id_);
        accepted->set_detached(detached_);
        accepted->set_tenant(tenant_);
        accepted->set_input_bytes(spec_.input_bytes());
        accepted->set_retention_seconds(absl::ToDoubleSeconds(registry_->retention()));
        cursor.phase = WatchCursor::Phase::kSnapshot;
        return Next::kEvent;
      }
      case WatchCursor::Phase::kSnapshot: {
        if (!cursor.snapshot_built) {
          const uint32_t readable = ReadableLevelsLocked();
          if (cursor.from_level < readable) {
            BuildSnapshotLocked(cursor);
          } else if (final_set_) {
            if (status_.ok()) {
              cursor.phase = WatchCursor::Phase::kEnded;
              status = grpc::Status(
                  grpc::StatusCode::OUT_OF_RANGE,
                  absl::StrCat("job ", id_, " has ", readable, " levels (0 to ", readable - 1,
                               "); level ", cursor.from_level, " is past its last"));
              return Next::kEnd;
            }
            cursor.phase = WatchCursor::Phase::kFinal;
            continue;
          } else {
            return wait();
          }
        }
        const std::vector<uint32_t>& labels =
            cursor.labels != nullptr ? *cursor.labels : snapshot_labels_;
        const size_t per_piece = std::max<size_t>(1024, (max_event_bytes_ - kBatchOverhead) / 5);
        const size_t first = cursor.snapshot_sent;
        const size_t end = std::min(labels.size(), first + per_piece);
        v1::LevelSnapshot* snapshot = event.mutable_snapshot();
        snapshot->set_level(cursor.from_level);
        if (cursor.from_level == 0) {
          snapshot->set_cluster_count(snapshot_cluster_count_);
          snapshot->set_energy(snapshot_energy_);
        } else {
          snapshot->set_cluster_count(levels_[cursor.from_level - 1].cluster_count);
          snapshot->set_energy(levels_[cursor.from_level - 1].energy);
        }
        snapshot->set_first_element(static_cast<uint32_t>(first));
        snapshot->set_total_elements(static_cast<uint32_t>(labels.size()));
        snapshot->mutable_labels()->Add(labels.begin() + static_cast<ptrdiff_t>(first),
                                        labels.begin() + static_cast<ptrdiff_t>(end));
        cursor.snapshot_sent = end;
        if (end == labels.size()) {
          cursor.labels.reset();
          cursor.phase = WatchCursor::Phase::kLevels;
        }
        return Next::kEvent;
      }
      case WatchCursor::Phase::kLevels: {
        const uint32_t readable = ReadableLevelsLocked();
        if (cursor.next_level < readable) {
          FillLevelBatchLocked(cursor, *event.mutable_levels());
          return Next::kEvent;
        }
        if (final_set_) {
          if (cursor.resume && status_.ok() && cursor.next_level > readable) {
            cursor.phase = WatchCursor::Phase::kEnded;
            status = grpc::Status(grpc::StatusCode::OUT_OF_RANGE,
                                  absl::StrCat("job ", id_, " has ", readable, " levels; level ",
                                               cursor.from_level, " is past its last"));
            return Next::kEnd;
          }
          cursor.phase = WatchCursor::Phase::kFinal;
          continue;
        }
        return wait();
      }
      case WatchCursor::Phase::kFinal:
        event = final_event_;
        status = status_;
        cursor.phase = WatchCursor::Phase::kEnded;
        return Next::kEvent;
      case WatchCursor::Phase::kEnded:
        status = status_;
        return Next::kEnd;
    }
  }
}

// ---------------------------------------------------------------------------------------

JobRegistry::JobRegistry(JobRegistryOptions options)
    : options_(options), kept_(options.kept_bytes_limit) {}

void JobRegistry::Add(std::shared_ptr<JobRecord> record) {
  std::lock_guard<std::mutex> lock(mutex_);
  order_.push_back(record->id());
  records_[record->id()] = std::move(record);
  // Over the count limit: the oldest ended jobs go.
  for (size_t i = 0; records_.size() > options_.max_records && i < order_.size();) {
    auto it = records_.find(order_[i]);
    if (it != records_.end() && it->second->ended()) {
      DropLocked(order_[i],
                 absl::StrCat("dropped at ", Timestamp(absl::Now()), ": the server keeps at most ",
                              options_.max_records, " jobs and newer ones came"));
    } else {
      ++i;
    }
  }
}

void JobRegistry::Remove(const std::string& id) {
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = records_.find(id);
  if (it == records_.end()) return;
  kept_.Release(it->second->DropLevels("refused"));
  records_.erase(it);
  order_.erase(std::remove(order_.begin(), order_.end(), id), order_.end());
}

absl::StatusOr<std::shared_ptr<JobRecord>> JobRegistry::Find(const std::string& id,
                                                             const std::string& tenant) {
  Sweep();
  std::lock_guard<std::mutex> lock(mutex_);
  // Another tenant's job, kept or dropped, answers exactly like an id never issued.
  auto it = records_.find(id);
  if (it != records_.end() && it->second->tenant() == tenant) return it->second;
  auto dropped = dropped_reasons_.find(id);
  if (it == records_.end() && dropped != dropped_reasons_.end() &&
      dropped->second.first == tenant) {
    return absl::NotFoundError(absl::StrCat("job ", id, ": ", dropped->second.second));
  }
  return absl::NotFoundError(
      absl::StrCat("no job '", id,
                   "' on this server (a job id belongs to the server that accepted the "
                   "job; an ended job's results are kept ",
                   absl::FormatDuration(options_.retention), ")"));
}

std::vector<v1::JobSummary> JobRegistry::List(const std::string& tenant, const std::string* owner) {
  Sweep();
  std::lock_guard<std::mutex> lock(mutex_);
  const absl::Time now = absl::Now();
  std::vector<v1::JobSummary> jobs;
  for (const std::string& id : order_) {
    const std::shared_ptr<JobRecord>& record = records_.at(id);
    if (record->tenant() != tenant) continue;
    if (owner != nullptr && record->owner() != *owner) continue;
    jobs.push_back(record->Summary(now, options_.retention));
  }
  return jobs;
}

uint32_t JobRegistry::ActiveJobs(const std::string& tenant) {
  std::lock_guard<std::mutex> lock(mutex_);
  uint32_t active = 0;
  for (const auto& [id, record] : records_) {
    if (record->tenant() == tenant && !record->ended()) ++active;
  }
  return active;
}

bool JobRegistry::ReserveKept(uint64_t bytes, const JobRecord* for_record) {
  if (kept_.TryReserve(bytes)) return true;
  std::lock_guard<std::mutex> lock(mutex_);
  for (size_t i = 0; i < order_.size();) {
    if (kept_.TryReserve(bytes)) return true;
    const std::shared_ptr<JobRecord>& record = records_.at(order_[i]);
    // An attached job's caller has its levels: it never drops a detached job's.
    if (record.get() != for_record && record->ended() && record->kept_bytes() > 0 &&
        (for_record->detached() || !record->detached())) {
      DropLocked(order_[i], absl::StrCat("its results were dropped at ", Timestamp(absl::Now()),
                                         " to make room for newer jobs' (the server keeps ",
                                         options_.kept_bytes_limit >> 20, " MiB of results)"));
    } else {
      ++i;
    }
  }
  return kept_.TryReserve(bytes);
}

void JobRegistry::Sweep() {
  std::lock_guard<std::mutex> lock(mutex_);
  const absl::Time now = absl::Now();
  for (size_t i = 0; i < order_.size();) {
    const std::shared_ptr<JobRecord>& record = records_.at(order_[i]);
    const absl::Time ended_at = record->ended() ? record->ended_at() : absl::InfiniteFuture();
    if (ended_at != absl::InfiniteFuture() && now - ended_at > options_.retention) {
      DropLocked(order_[i], absl::StrCat("its results were dropped at ", Timestamp(now), ", ",
                                         absl::FormatDuration(options_.retention),
                                         " after it ended (the server's retention time)"));
    } else {
      ++i;
    }
  }
}

size_t JobRegistry::size() {
  std::lock_guard<std::mutex> lock(mutex_);
  return records_.size();
}

void JobRegistry::DropLocked(std::string id, const std::string& reason) {
  auto it = records_.find(id);
  if (it == records_.end()) return;
  kept_.Release(it->second->DropLevels(reason));
  const std::string tenant = it->second->tenant();
  records_.erase(it);
  order_.erase(std::find(order_.begin(), order_.end(), id));
  dropped_.fetch_add(1, std::memory_order_relaxed);
  constexpr size_t kMaxDroppedNotes = 4096;
  dropped_order_.push_back(id);
  dropped_reasons_[id] = {tenant, reason};
  if (dropped_order_.size() > kMaxDroppedNotes) {
    dropped_reasons_.erase(dropped_order_.front());
    dropped_order_.pop_front();
  }
}

// ---------------------------------------------------------------------------------------

bool RecordingChannel::Emit(v1::JobEvent event) {
  record_->Keep(event);
  if (call_->Emit(std::move(event))) return true;
  if (!call_->released() || call_->cancelled()) return false;
  // The reader was cut off and the job released to its record, which must keep its
  // levels for it to be worth running on.
  if (!record_->levels_dropped()) return true;
  Abort(grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                     "its reader was cut off and its levels do not fit the server's memory for "
                     "kept results; the job was cancelled"));
  return false;
}

void RecordingChannel::Finish(v1::JobEvent final_event, const grpc::Status& status) {
  record_->Finish(final_event, status);
  call_->Finish(std::move(final_event), status);
}

void RecordingChannel::Abort(const grpc::Status& status) {
  record_->Abort(status);
  call_->Abort(status);
}

}  // namespace mlclust::server
