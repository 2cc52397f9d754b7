// The client library: submit a job, receive its events, rebuild its levels.
#ifndef MLCLUST_CLIENT_CLIENT_H_
#define MLCLUST_CLIENT_CLIENT_H_

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/time/time.h"
#include "core/hierarchy/hierarchy.h"
#include "grpcpp/channel.h"
#include "mlclust/v1/mlclust.pb.h"

namespace mlclust::client {

// A channel to a server at "host:port" (plaintext), accepting messages of any size.
std::shared_ptr<grpc::Channel> Connect(const std::string& address);

struct ConnectOptions {
  // PEM file of the certificate authority that signed the server's certificate: TLS.
  // Empty: plaintext.
  std::string tls_ca_file;
  // With TLS and a server that checks client certificates (serve --tls-client-ca): this
  // client's certificate and key (PEM files).
  std::string tls_cert_file;
  std::string tls_key_file;
  // A file whose first non-empty, non-comment line is the bearer token sent with every
  // call (the server's --auth-token-file names its tenant). The token is never printed.
  std::string auth_token_file;
};

// A channel to `address` with TLS and a bearer token as `options` say. INVALID_ARGUMENT
// when a file cannot be read or holds no token, or for a token without TLS (a bearer
// token never travels in plaintext).
absl::StatusOr<std::shared_ptr<grpc::Channel>> Connect(const std::string& address,
                                                       const ConnectOptions& options);

// The levels a job's streams delivered, kept across calls for one job: a job whose replica
// was lost is submitted again elsewhere (client/replicas.h) and its new stream continues
// the levels held. Pass the same ReceivedLevels to each RunJob (or each WatchJob) call
// for the job. The first call fills it; a later call's stream repeats the levels held
// first (the job runs again from the start: it is a pure function of its input and spec,
// seed included), and they are checked, each the same level number, cluster count,
// energy and triplets as held (DATA_LOSS naming the level otherwise: the replicas do not
// compute the same levels), and skipped: not applied again and not passed to on_event
// again (a batch holding both is passed on trimmed to the new levels). The levels after
// them are added. The JobResult of the call that succeeds holds every level once (moved
// out of here).
class ReceivedLevels {
 public:
  ReceivedLevels();
  ~ReceivedLevels();
  ReceivedLevels(const ReceivedLevels&) = delete;
  ReceivedLevels& operator=(const ReceivedLevels&) = delete;

  // Complete levels held (the start counts one; 0 before a snapshot was complete).
  size_t levels() const;
  // The last call's stream carried the job's final event (done or failed): the job ended
  // there, its status is the job's own and not a lost stream.
  bool saw_final() const;

  struct State;  // the library's
  State& state() { return *state_; }

 private:
  std::unique_ptr<State> state_;
};

struct RunOptions {
  // Input is uploaded in chunks of this many bytes (the server accepts up to 64 MiB).
  size_t chunk_bytes = size_t{1} << 20;
  // The call is cancelled (and the job with it) after this long.
  absl::Duration deadline = absl::InfiniteDuration();
  // Called for every event as it arrives, on the calling thread (for progress lines).
  std::function<void(const v1::JobEvent&)> on_event;
  // Asks for raw uint32 triplets (JobSpec.packed_triplets, issue 13): no varint coding on
  // either side. The levels received are the same either way.
  bool packed_triplets = true;
  // Rebuild the labels of the level `--clusters K` writes while the stream arrives
  // (JobResult::chosen_labels): the last level with exactly this many clusters, else the
  // first with fewer (0: none). Saves replaying the hierarchy after the stream ends.
  uint32_t labels_for_clusters = 0;
  // Events are read (and parsed) on a reader thread into a queue of at most this many,
  // while the calling thread rebuilds the levels (issue 13); 0: one thread.
  size_t read_ahead_events = 16;
  // The levels an earlier call for the same job received (ReceivedLevels); null: none.
  ReceivedLevels* received = nullptr;
};

struct JobResult {
  std::string job_id;
  // Level 0 of `hierarchy` is the first level the server sent (the snapshot).
  HierarchyLog hierarchy;
  v1::Done done;
  // The picture JobSpec.preview asked for (empty png when none came).
  v1::Preview preview;
  // The job's level number of `hierarchy`'s level 0 (WatchJob's from_level; 0 for RunJob).
  uint32_t first_level = 0;
  // RunOptions::labels_for_clusters: the level chosen and its labels, rebuilt as the levels
  // arrived (equal to hierarchy.LabelsAt(*chosen_level)); nullopt when none was asked or
  // no level has that many clusters or fewer.
  std::optional<size_t> chosen_level;
  std::vector<ClusterId> chosen_labels;
};

// Runs one job to the end: sends `spec` (its input_bytes is set here) and `input`, then
// rebuilds the hierarchy from the snapshot and level batches. On failure returns the
// server's status and message (INVALID_ARGUMENT for bad input, RESOURCE_EXHAUSTED for a
// full queue, ...); DATA_LOSS if the stream of levels is inconsistent.
absl::StatusOr<JobResult> RunJob(const std::shared_ptr<grpc::Channel>& channel, v1::JobSpec spec,
                                 std::string_view input, const RunOptions& options = {});

// Submits a detached job (JobSpec.detach): uploads `input` and returns the server's
// Accepted event (the job id) as soon as the job is queued; the job runs on.
absl::StatusOr<v1::Accepted> SubmitDetached(const std::shared_ptr<grpc::Channel>& channel,
                                            v1::JobSpec spec, std::string_view input,
                                            const RunOptions& options = {});

struct WatchOptions {
  // The first level wanted, sent as a snapshot (0: the job's first level).
  uint32_t from_level = 0;
  // The whole watch ends (the job does not) after this long.
  absl::Duration deadline = absl::InfiniteDuration();
  // A stream that breaks (UNAVAILABLE, a reset connection) is resumed where it stopped, at
  // most this many times in a row, `resume_delay` apart.
  int max_resumes = 5;
  absl::Duration resume_delay = absl::Milliseconds(500);
  std::function<void(const v1::JobEvent&)> on_event;
  // Called before each resume, with the status that broke the stream.
  std::function<void(const absl::Status&)> on_resume;
  // The levels an earlier watch of the same job's spec received, on another replica
  // (ReceivedLevels): the watch starts from their first level; null: none.
  ReceivedLevels* received = nullptr;
};

// Reads a job's levels (Watch; detached or not): level `from_level` and every level after it
// (level 0 of the returned hierarchy is `from_level` of the job), to the job's end. On
// failure the server's status (NOT_FOUND once its results were dropped, with a message
// saying when and why).
absl::StatusOr<JobResult> WatchJob(const std::shared_ptr<grpc::Channel>& channel,
                                   const std::string& job_id, const WatchOptions& options = {});

// A stream that broke on the way (UNAVAILABLE; a reset stream: INTERNAL RST_STREAM,
// UNKNOWN "Stream removed") rather than a job or request that failed.
bool IsBrokenStream(const absl::Status& status);

// Cancels a job; returns its state after the call.
absl::StatusOr<std::string> CancelJob(const std::shared_ptr<grpc::Channel>& channel,
                                      const std::string& job_id,
                                      absl::Duration deadline = absl::Seconds(30));

// The jobs of the caller's tenant.
absl::StatusOr<v1::JobList> ListJobs(const std::shared_ptr<grpc::Channel>& channel,
                                     absl::Duration deadline = absl::Seconds(30));

// The labels at `level` renumbered 0..k-1 in order of first appearance, so that outputs
// do not depend on the server's internal cluster ids.
std::vector<uint32_t> CompactLabels(std::span<const ClusterId> labels);

}  // namespace mlclust::client

#endif  // MLCLUST_CLIENT_CLIENT_H_
