// Runs one job: decode, validate, measure, cluster, stream the levels.
#ifndef MLCLUST_SERVER_JOB_RUNNER_H_
#define MLCLUST_SERVER_JOB_RUNNER_H_

#include <string>

#include "absl/status/statusor.h"
#include "server/job.h"

namespace mlclust::gpu {
class GlContext;
}

namespace mlclust::server {

struct JobRunnerContext {
  // The worker's GL context, or nullptr when the server runs without a GPU. Only used on
  // the thread that created it (the worker's).
  gpu::GlContext* gl = nullptr;
  std::string gl_renderer;
  // A software renderer (llvmpipe) is slower than the CPU path for these kernels, so
  // device "auto" uses it only when it is hardware; device "gpu" uses it regardless.
  bool gl_is_software = false;
  // Triplets per LevelBatch when the job does not say.
  uint32_t default_batch_triplets = 1 << 16;
};

struct JobOutcome {
  v1::Done done;  // filled on success
};

// Runs `job` to the end and streams its events (progress, snapshot, level batches) to
// job.events. Does not send the final event: the caller does, from the returned status.
// INVALID_ARGUMENT for bad input (with the validation message), UNIMPLEMENTED for inputs
// and algorithms this server does not run, CANCELLED if the call went away.
absl::StatusOr<JobOutcome> RunJob(Job& job, const JobRunnerContext& context);

// Fills Accepted's description of the input (face_ids, face_order, draco_method) from
// `input`'s Draco header and metadata, without decoding it; nothing for points.
void DescribeInput(const v1::JobSpec& spec, std::string_view input, v1::Accepted& accepted);

}  // namespace mlclust::server

#endif  // MLCLUST_SERVER_JOB_RUNNER_H_
