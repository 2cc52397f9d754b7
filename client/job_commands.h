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
#include "client/client.h"
#include "grpcpp/channel.h"
#include "mlclust/v1/mlclust.pb.h"

namespace mlclust::cli {

// --server ADDR and the connection flags.
struct ServerFlags {
  std::string server;  // empty: none given
  client::ConnectOptions connect;
  // --deadline SECONDS: every call's gRPC deadline (a Run's job is cancelled when it hits).
  absl::Duration deadline = absl::InfiniteDuration();
};

// The names of the connection flags, for a command's list of known options: deadline,
// tls-ca, tls-cert, tls-key, auth-token-file.
std::vector<std::string> ConnectionFlagNames();

// Reads the flags through `get` (the value of --NAME, or nullopt). INVALID_ARGUMENT for a
// bad --deadline.
absl::StatusOr<ServerFlags> ServerFlagsFrom(
    const std::function<std::optional<std::string>(const std::string&)>& get);

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

// Usage of watch, cancel and jobs, and of the connection flags.
const char* JobCommandsUsage();
const char* ConnectionFlagsUsage();

bool IsJobCommand(const std::string& name);  // watch, cancel, jobs
// Runs `mlclust watch|cancel|jobs` with the arguments after the command name. Returns the
// exit code: 0, 2 for bad arguments, 1 when the server refuses or fails.
int RunJobCommand(const std::string& name, int argc, char** argv);

}  // namespace mlclust::cli

#endif  // MLCLUST_CLIENT_JOB_COMMANDS_H_
