// The client library: submit a job, receive its events, rebuild its levels.
#ifndef MLCLUST_CLIENT_CLIENT_H_
#define MLCLUST_CLIENT_CLIENT_H_

#include <cstdint>
#include <functional>
#include <memory>
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

struct RunOptions {
  // Input is uploaded in chunks of this many bytes (the server accepts up to 64 MiB).
  size_t chunk_bytes = size_t{1} << 20;
  // The call is cancelled (and the job with it) after this long.
  absl::Duration deadline = absl::InfiniteDuration();
  // Called for every event as it arrives, on the calling thread (for progress lines).
  std::function<void(const v1::JobEvent&)> on_event;
};

struct JobResult {
  std::string job_id;
  // Level 0 of `hierarchy` is the first level the server sent (the snapshot).
  HierarchyLog hierarchy;
  v1::Done done;
  // The picture JobSpec.preview asked for (empty png when none came).
  v1::Preview preview;
};

// Runs one job to the end: sends `spec` (its input_bytes is set here) and `input`, then
// rebuilds the hierarchy from the snapshot and level batches. On failure returns the
// server's status and message (INVALID_ARGUMENT for bad input, RESOURCE_EXHAUSTED for a
// full queue, ...); DATA_LOSS if the stream of levels is inconsistent.
absl::StatusOr<JobResult> RunJob(const std::shared_ptr<grpc::Channel>& channel, v1::JobSpec spec,
                                 std::string_view input, const RunOptions& options = {});

// The labels at `level` renumbered 0..k-1 in order of first appearance, so that outputs
// do not depend on the server's internal cluster ids.
std::vector<uint32_t> CompactLabels(std::span<const ClusterId> labels);

}  // namespace mlclust::client

#endif  // MLCLUST_CLIENT_CLIENT_H_
