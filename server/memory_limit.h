// The memory a server's options let it use at most, and the memory it is given (the
// cgroup's limit), so `mlclust serve` refuses at start a configuration that does not fit
// and the deployment manifests take their requests and limits from one formula.
#ifndef MLCLUST_SERVER_MEMORY_LIMIT_H_
#define MLCLUST_SERVER_MEMORY_LIMIT_H_

#include <cstdint>
#include <optional>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "server/server.h"

namespace mlclust::server {

// Memory one running job takes per input byte at most (measured on meshes: the decoded
// mesh, its dual graph and the hierarchy; docker/k8s/base/deployment.yaml), and what the
// process takes beside the budgets (code, gRPC, allocator slack).
inline constexpr uint64_t kJobBytesPerInputByte = 41;
inline constexpr uint64_t kProcessBytes = uint64_t{512} << 20;

struct MemoryNeeded {
  uint64_t running_jobs = 0;   // (1 + cpu_workers) jobs of max_input_bytes
  uint64_t queued_inputs = 0;  // max_queued_input_bytes
  uint64_t uploads = 0;        // max_upload_bytes_in_flight
  uint64_t unread_events = 0;  // result_server_budget_bytes
  uint64_t kept_results = 0;   // kept_results_bytes
  uint64_t process = kProcessBytes;
  // The budgets the server enforces, and the process.
  uint64_t budgets() const {
    return queued_inputs + uploads + unread_events + kept_results + process;
  }
  // With the running jobs' estimate: the figure for a container's memory.
  uint64_t total() const { return running_jobs + budgets(); }
};

// The most memory `options` let the server use: its budgets, the running jobs and the
// process.
MemoryNeeded MemoryNeededFor(const ServerOptions& options);

// The memory limit of the cgroup this process runs in: cgroup v2's memory.max under
// `root` (for the process's own group, from /proc/self/cgroup), else v1's
// memory/memory.limit_in_bytes; nullopt where there is none ("max", or v1's "no limit").
std::optional<uint64_t> CgroupMemoryLimit(const std::string& root = "/sys/fs/cgroup");

// OK when `needed.budgets()` fit `limit` (or there is no limit); else INVALID_ARGUMENT
// naming every part and the flags that shrink them. The running jobs' share is an
// estimate, not a budget: RunningJobsFit says whether the total fits too (a warning).
absl::Status CheckMemoryFits(const MemoryNeeded& needed, std::optional<uint64_t> limit);
bool RunningJobsFit(const MemoryNeeded& needed, std::optional<uint64_t> limit);

}  // namespace mlclust::server

#endif  // MLCLUST_SERVER_MEMORY_LIMIT_H_
