// Several servers (replicas) behind one --server: "a:1,b:2,c:3" or a DNS name that resolves
// to several addresses ("dns:///name:port"). Jobs go to the least loaded replica (GetStats:
// queue depth plus running jobs; ties broken at random so that concurrent clients spread),
// and a job is tried on the next replica when one is unreachable, draining or full BEFORE
// it accepted the job.
//
// A replica lost AFTER it accepted the job (it died, was drained with the job still
// running, or the stream broke before the job's final event: UNAVAILABLE, a reset stream)
// does not lose the job: it is submitted again to the next healthy replica, at most
// ReplicaOptions::max_resubmits times (--resubmit N), each time said through on_resubmit.
// That is safe because a job is a pure function of its input and spec (seed included): run
// again, it gives the same levels and has no other effect. The levels received are kept
// (ReceivedLevels): the new stream's first levels are checked against them (DATA_LOSS if a
// replica computed different levels) and skipped, so the result and on_event see each level
// once. A job that failed or was cancelled on its replica, or that hit the caller's own
// deadline, is not submitted again: that end is the job's.
//
// Detached jobs: replicas share nothing. A detached job's id names the replica that holds it
// and its levels, "HOST:PORT/" + the server's opaque id (never parsed beyond that); if that
// replica is lost, so is the job there. The rule for a client that must not lose it: keep
// the job's spec and input (or what rebuilds them) beside the id, and when a watch finds
// the replica gone (UNAVAILABLE), submit the job again and watch the new id: the levels are
// the same. WatchOnReplicas does that; the Python client's watch(..., resubmit=...) too.
#ifndef MLCLUST_CLIENT_REPLICAS_H_
#define MLCLUST_CLIENT_REPLICAS_H_

#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/time/time.h"
#include "client/client.h"
#include "mlclust/v1/mlclust.pb.h"

namespace mlclust::client {

// True when `servers` names several replicas: a comma-separated list or a dns: URI.
bool NamesReplicas(const std::string& servers);

// The replicas `servers` names, each "HOST:PORT" ([IPv6]:PORT), duplicates removed:
// the items of a comma-separated list as written, or every address a "dns:///NAME:PORT"
// (or "dns:NAME:PORT") resolves to. INVALID_ARGUMENT for an empty item or a missing port,
// NOT_FOUND for a name that does not resolve.
absl::StatusOr<std::vector<std::string>> ResolveReplicas(const std::string& servers);

// A job id with its replica: "HOST:PORT/JOBID".
std::string ReplicaJobId(const std::string& replica, const std::string& job_id);

struct SplitJobId {
  std::string replica;  // "HOST:PORT"
  std::string job_id;   // the server's id
};
// The replica and server id of "HOST:PORT/JOBID"; nullopt for an id without a replica.
std::optional<SplitJobId> SplitReplicaJobId(const std::string& id);

// What on_resubmit is told.
struct Resubmission {
  std::string lost_replica;  // "HOST:PORT", that accepted the job and was lost
  absl::Status status;       // how the stream ended
  int attempt = 0;           // 1 for the first resubmission
  int max_resubmits = 0;
  size_t levels_kept = 0;  // complete levels received so far (the start counts one)
};

struct ReplicaOptions {
  ConnectOptions connect;
  // Try the replicas in the order given (a primary, then fallbacks) instead of the least
  // loaded first (--spread in-order).
  bool in_order = false;
  // How long GetStats may take on each replica when choosing one.
  absl::Duration probe_deadline = absl::Seconds(2);
  // Called when a replica did not accept the job and the next one is tried.
  std::function<void(const std::string& replica, const absl::Status& status)> on_retry;
  // A job whose replica was lost after accepting it is submitted again at most this many
  // times (--resubmit N; 0: never).
  int max_resubmits = 2;
  // Called before each such submission.
  std::function<void(const Resubmission&)> on_resubmit;
};

// The order in which the replicas are tried: those answering GetStats and not draining,
// least queue depth plus running jobs first (ties in a random order), then the others;
// with options.in_order, `replicas` as given.
std::vector<std::string> OrderReplicas(const std::vector<std::string>& replicas,
                                       const ReplicaOptions& options);

// True for a failure that means the replica did not take the job, so another may:
// UNAVAILABLE (unreachable, died, draining) or RESOURCE_EXHAUSTED (queue or budgets full).
bool TryAnotherReplica(const absl::Status& status);

// RunJob on the replicas in OrderReplicas' order until one accepts the job and runs it to
// its end (the deadline of `run_options` is one for all the attempts); a replica lost after
// accepting it: the job is submitted again (the header comment). `replica` receives the one
// that ran it (or the last tried). UNAVAILABLE naming every replica when none accepted it,
// or the lost ones once max_resubmits is spent; DATA_LOSS when a replica that ran it again
// sent levels other than those received; a job that failed on its replica, its status with
// the replica named.
absl::StatusOr<JobResult> RunJobOnReplicas(const std::vector<std::string>& replicas,
                                           const v1::JobSpec& spec, std::string_view input,
                                           const RunOptions& run_options,
                                           const ReplicaOptions& options, std::string* replica);

// SubmitDetached likewise; the Accepted event's job_id is "HOST:PORT/JOBID".

// Watches a detached job whose spec and input the caller kept (the rule of the header
// comment): WatchJob on the replica `job_id` ("HOST:PORT/JOBID") names; when that replica
// is lost (UNAVAILABLE after WatchJob's own resumes, before the job's final event), the job
// is submitted again, detached, to the next healthy replica (SubmitDetachedOnReplicas; the
// lost one last) and watched there, at most options.max_resubmits times, the levels
// received kept and checked as for RunJobOnReplicas. `final_job_id` receives the id of the
// job that ended (new after a resubmission; print it). A failed job, a watch's deadline or
// NOT_FOUND (the replica answers and no longer holds the job) end the call as they are.
absl::StatusOr<JobResult> WatchOnReplicas(const std::vector<std::string>& replicas,
                                          const std::string& job_id, const v1::JobSpec& spec,
                                          std::string_view input, const WatchOptions& watch,
                                          const ReplicaOptions& options, std::string* final_job_id);
absl::StatusOr<v1::Accepted> SubmitDetachedOnReplicas(
    const std::vector<std::string>& replicas, const v1::JobSpec& spec, std::string_view input,
    const RunOptions& run_options, const ReplicaOptions& options, std::string* replica);

// A failed call about job `job_id` on `replica` in words: UNAVAILABLE says that the replica
// holding the job is gone with its jobs (replicas share nothing) and that the job may be
// submitted again; other codes keep theirs with the replica named.
absl::Status ExplainReplicaFailure(const absl::Status& status, const std::string& replica,
                                   const std::string& job_id);

}  // namespace mlclust::client

#endif  // MLCLUST_CLIENT_REPLICAS_H_
