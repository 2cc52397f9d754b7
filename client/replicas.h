// Several servers (replicas) behind one --server: "a:1,b:2,c:3" or a DNS name that resolves
// to several addresses ("dns:///name:port"). Jobs go to the least loaded replica (GetStats:
// queue depth plus running jobs; ties broken at random so that concurrent clients spread),
// and a job is tried on the next replica when one is unreachable, draining or full BEFORE
// it accepted the job. A job a replica accepted is never submitted again elsewhere (it may
// have run): its failure is reported as it is. A detached job's id names its replica:
// "HOST:PORT/JOBID".
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

struct ReplicaOptions {
  ConnectOptions connect;
  // Try the replicas in the order given (a primary, then fallbacks) instead of the least
  // loaded first (--spread in-order).
  bool in_order = false;
  // How long GetStats may take on each replica when choosing one.
  absl::Duration probe_deadline = absl::Seconds(2);
  // Called when a replica did not accept the job and the next one is tried.
  std::function<void(const std::string& replica, const absl::Status& status)> on_retry;
};

// The order in which the replicas are tried: those answering GetStats and not draining,
// least queue depth plus running jobs first (ties in a random order), then the others;
// with options.in_order, `replicas` as given.
std::vector<std::string> OrderReplicas(const std::vector<std::string>& replicas,
                                       const ReplicaOptions& options);

// True for a failure that means the replica did not take the job, so another may:
// UNAVAILABLE (unreachable, died, draining) or RESOURCE_EXHAUSTED (queue or budgets full).
bool TryAnotherReplica(const absl::Status& status);

// RunJob on the replicas in OrderReplicas' order until one accepts the job (the deadline
// of `run_options` is one for all the attempts). `replica`
// receives the one that accepted it (or the last tried). UNAVAILABLE naming every replica
// when none accepted it; a replica that fails after accepting the job fails the call
// (the message says that the job was not submitted again).
absl::StatusOr<JobResult> RunJobOnReplicas(const std::vector<std::string>& replicas,
                                           const v1::JobSpec& spec, std::string_view input,
                                           const RunOptions& run_options,
                                           const ReplicaOptions& options, std::string* replica);

// SubmitDetached likewise; the Accepted event's job_id is "HOST:PORT/JOBID".
absl::StatusOr<v1::Accepted> SubmitDetachedOnReplicas(
    const std::vector<std::string>& replicas, const v1::JobSpec& spec, std::string_view input,
    const RunOptions& run_options, const ReplicaOptions& options, std::string* replica);

// A failed call about job `job_id` on `replica` in words: UNAVAILABLE says that the replica
// holding the job is gone and that its jobs are not moved elsewhere; other codes keep
// theirs with the replica named.
absl::Status ExplainReplicaFailure(const absl::Status& status, const std::string& replica,
                                   const std::string& job_id);

}  // namespace mlclust::client

#endif  // MLCLUST_CLIENT_REPLICAS_H_
