// Detached jobs on the command line: `mlclust watch`, `mlclust cancel`, `mlclust jobs`,
// the `--detach` of mesh and points, and the connection flags every command that talks to
// a server shares (--deadline, TLS, bearer token). client/main.cc only dispatches here.
#ifndef MLCLUST_CLIENT_JOB_COMMANDS_H_
#define MLCLUST_CLIENT_JOB_COMMANDS_H_

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/time/time.h"
#include "client/cli.h"
#include "client/client.h"
#include "client/replicas.h"
#include "grpcpp/channel.h"
#include "mlclust/v1/mlclust.pb.h"

namespace mlclust::cli {

// --server ADDR and the connection flags.
struct ServerFlags {
  std::string server;  // empty: none given
  client::ConnectOptions connect;
  // --deadline SECONDS: every call's gRPC deadline (a Run's job is cancelled when it hits).
  absl::Duration deadline = absl::InfiniteDuration();
  // --spread least-loaded|in-order: with several servers (client/replicas.h), the least
  // loaded first, or the order given.
  bool spread_in_order = false;
  // --resubmit N: with several servers, a job whose replica was lost after accepting it is
  // submitted again at most N times (client::ReplicaOptions::max_resubmits).
  int max_resubmits = 2;
};

// The replica options of `flags`, with a line on stderr (unless `quiet`) for each replica
// that did not accept a job and for each resubmission.
client::ReplicaOptions ReplicaOptionsFrom(const ServerFlags& flags, bool quiet);

// Reads --server and the connection flags (cli.h's ConnectionFlags). INVALID_ARGUMENT for a
// bad --deadline or --spread.
absl::StatusOr<ServerFlags> ServerFlagsFrom(const Arguments& args);

// A channel to flags.server with TLS and the token as the flags say.
absl::StatusOr<std::shared_ptr<grpc::Channel>> ConnectTo(const ServerFlags& flags);

// A call's failure in words where the deadline was hit (DEADLINE_EXCEEDED after
// --deadline), else `status` unchanged. `what`: "the job", "the watch".
absl::Status ExplainDeadline(const absl::Status& status, const ServerFlags& flags,
                             const std::string& what);

// `mlclust mesh|points ... --detach`: submits the job detached and prints its id as the
// last line of stdout (a line about it before that unless `quiet`). Returns the exit code.
int SubmitDetachedCommand(const ServerFlags& flags, const v1::JobSpec& spec,
                          const std::string& payload, bool quiet);

// `mlclust watch`, `mlclust cancel`, `mlclust jobs`: exit code 0, 2 for bad arguments, 1
// when the server refuses or fails.
Command WatchCommand();
Command CancelCommand();
Command JobsCommand();

}  // namespace mlclust::cli

#endif  // MLCLUST_CLIENT_JOB_COMMANDS_H_
