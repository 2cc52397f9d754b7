// A Watch or a Cancel request as the server handles it after admission (server/server.cc,
// ServiceImpl::Watch and ServiceImpl::Cancel): the request from its wire bytes, its job id
// looked up in the server's JobRegistry (JobRegistry::Find, server/job_record.h) for the
// caller's tenant, the id made safe to log (LogSafe, server/log.h), then for Watch a cursor
// set from from_level and resume as WatchCall sets it, read to the end (NextEvent), and for
// Cancel the job's record aborted with CANCELLED, as Cancel does, then read to the end.
// Not covered: the gRPC framing, tokens and admission, which need a running server.
//
// The registry holds three jobs: an ended one of tenant "" with ten levels, a running one
// of tenant "" with its levels so far, and an ended one of tenant "beta" (the ids are in
// the seeds, fuzz/corpus/watch_cancel/).
//
// Input: one byte (bit 0: a CancelRequest, else a WatchRequest; bit 1: the caller is
// tenant "beta", else tenant ""), then the request's bytes.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

#include "fuzz/fuzz_check.h"
#include "mlclust/v1/mlclust.pb.h"
#include "server/job_record.h"
#include "server/log.h"
#include "tests/server/hierarchy_events.h"

namespace {

using mlclust::server::JobRecord;
using mlclust::server::JobRegistry;
using mlclust::server::JobRegistryOptions;
using mlclust::server::JobState;
using mlclust::server::WatchCursor;
namespace v1 = mlclust::v1;

constexpr char kEndedId[] = "job-00112233445566778899aabbccddeeff";
constexpr char kRunningId[] = "job-0123456789abcdef0123456789abcdef";
constexpr char kOtherTenantsId[] = "job-ffeeddccbbaa99887766554433221100";

// The registry tests' hierarchy (tests/server/hierarchy_events.h).
void EmitHierarchy(JobRecord& record, uint32_t n) {
  MLCLUST_FUZZ_CHECK(record.Emit(mlclust::server::test_data::HierarchySnapshot(n)));
  MLCLUST_FUZZ_CHECK(record.Emit(mlclust::server::test_data::HierarchyLevels(n)));
}

std::shared_ptr<JobRecord> AddJob(JobRegistry& registry, const std::string& id,
                                  const std::string& tenant, bool ended) {
  v1::JobSpec spec;
  spec.set_input_kind(v1::INPUT_KIND_DRACO_MESH);
  spec.set_detach(true);
  // Small events (1 KiB), so that a snapshot of 300 labels is split.
  auto record = std::make_shared<JobRecord>(&registry, id, tenant, spec, true, 1024);
  registry.Add(record);
  record->MarkRunning();
  EmitHierarchy(*record, ended ? 10 : 300);
  if (ended) {
    v1::JobEvent done;
    done.mutable_done()->set_levels(10);
    record->Finish(done, grpc::Status::OK);
  }
  return record;
}

// Reads `record` from `cursor` until its end, or until it would wait (a running job).
void ReadToEnd(JobRecord& record, WatchCursor cursor) {
  v1::JobEvent event;
  grpc::Status status;
  bool ended = false;
  for (int events = 0; events < 100000; ++events) {
    const JobRecord::Next next = record.NextEvent(cursor, event, status, nullptr);
    if (next == JobRecord::Next::kWait) {
      MLCLUST_FUZZ_CHECK(!record.ended());  // an ended job has nothing to wait for
      return;
    }
    if (next == JobRecord::Next::kEnd) {
      ended = true;
      break;
    }
    MLCLUST_FUZZ_CHECK(event.ByteSizeLong() <= 4096);  // split to about the 1 KiB asked
  }
  MLCLUST_FUZZ_CHECK(ended);  // 10 or 300 levels never take 100,000 events
  MLCLUST_FUZZ_CHECK(record.ended());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const bool cancel = (data[0] & 1) != 0;
  const std::string tenant = (data[0] & 2) != 0 ? "beta" : "";
  v1::WatchRequest watch;
  v1::CancelRequest cancel_request;
  const int bytes = static_cast<int>(size - 1);
  if (cancel ? !cancel_request.ParseFromArray(data + 1, bytes)
             : !watch.ParseFromArray(data + 1, bytes)) {
    return 0;
  }
  const std::string& id = cancel ? cancel_request.job_id() : watch.job_id();

  // What a log line carries of the id: no control character, bounded.
  const std::string logged = mlclust::server::LogSafe(id);
  for (const char c : logged) {
    const auto byte = static_cast<unsigned char>(c);
    MLCLUST_FUZZ_CHECK(byte >= 0x20 && byte != 0x7f);
  }
  MLCLUST_FUZZ_CHECK(logged.size() <= mlclust::server::kLoggedValueBytes + 32);

  JobRegistry registry(JobRegistryOptions{});
  std::shared_ptr<JobRecord> ended = AddJob(registry, kEndedId, "", true);
  std::shared_ptr<JobRecord> running = AddJob(registry, kRunningId, "", false);
  std::shared_ptr<JobRecord> others = AddJob(registry, kOtherTenantsId, "beta", true);

  absl::StatusOr<std::shared_ptr<JobRecord>> record = registry.Find(id, tenant);
  if (!record.ok()) {
    // Exactly the answer of a registry that never knew the id: another tenant's job
    // cannot be told from an unknown one.
    JobRegistry empty(JobRegistryOptions{});
    MLCLUST_FUZZ_CHECK(record.status() == empty.Find(id, tenant).status());
    MLCLUST_FUZZ_CHECK(record.status().code() == absl::StatusCode::kNotFound);
    return 0;
  }
  // Only the caller's own job, under exactly its id.
  MLCLUST_FUZZ_CHECK((*record)->id() == id && (*record)->tenant() == tenant);

  if (cancel) {
    const JobState before = (*record)->state();
    (*record)->Abort(grpc::Status(grpc::StatusCode::CANCELLED, "cancelled by a Cancel call"));
    // An ended job keeps its outcome; a running one is cancelled and ended.
    MLCLUST_FUZZ_CHECK((*record)->ended());
    MLCLUST_FUZZ_CHECK(before != JobState::kRunning || (*record)->state() == JobState::kCancelled);
    MLCLUST_FUZZ_CHECK(before == JobState::kRunning || (*record)->state() == before);
    ReadToEnd(**record, WatchCursor());
    return 0;
  }
  // The cursor as WatchCall sets it from the request.
  const WatchCursor cursor = mlclust::server::WatchCursorFor(watch.from_level(), watch.resume());
  ReadToEnd(**record, cursor);
  return 0;
}
