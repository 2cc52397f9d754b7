// Runs one job: decode, validate, measure, cluster, stream the levels.
#ifndef MLCLUST_SERVER_JOB_RUNNER_H_
#define MLCLUST_SERVER_JOB_RUNNER_H_

#include <string>

#include "absl/status/statusor.h"
#include "core/cluster/device_stages.h"
#include "core/plan/device_policy.h"
#include "server/job.h"

namespace mlclust::gpu {
class GlContext;
}

namespace mlclust::server {

struct JobRunnerContext {
  // The worker's GL context, for the preview; nullptr on a worker without one (the CPU
  // workers, a server without a GPU). Only used on the thread that created it.
  gpu::GlContext* gl = nullptr;
  // The stages on the GPU over that context (gpu/stages/gl_device_stages.h), run where the
  // plan puts a stage on the GPU; nullptr on a worker without one. Borrowed.
  DeviceStages* devices = nullptr;
  // The server's device as the device policy reads it (core/plan/device_policy.h): the
  // same on every worker of a server, so a job planned here and at submit agree.
  DeviceCaps device;
  // Triplets per LevelBatch when the job does not say.
  uint32_t default_batch_triplets = 1 << 16;
};

struct JobOutcome {
  v1::Done done;  // filled on success
};

// The plan of `spec` with its devices (core/plan/device_policy.h PlanDevices on `device`),
// for what the spec says of the input: points' count and dimensions, whether it is
// per-polygon (a mesh's faces are known once decoded: RunJob fits the plan to them then).
// The server plans at submit with it and picks the job's lane from the plan.
absl::StatusOr<JobPlan> PlanJobOnDevice(const v1::JobSpec& spec, const DeviceCaps& device);

// Runs `job` to the end and streams its events (progress, snapshot, level batches) to
// job.events. Runs job.plan (RunJob plans where it is empty); the stages run where the plan
// says (no fallback) and Done.devices names each as it ran. Does not send the final event: the
// caller does, from the returned status. INVALID_ARGUMENT for bad input (with the validation
// message), UNIMPLEMENTED for inputs and algorithms this server does not run, CANCELLED if the call
// went away.
absl::StatusOr<JobOutcome> RunJob(Job& job, const JobRunnerContext& context);

// Fills Accepted's description of the input (face_ids, face_order, draco_method) from
// `input`'s Draco header and metadata, without decoding it; nothing for points.
void DescribeInput(const v1::JobSpec& spec, std::string_view input, v1::Accepted& accepted);

// What the spec alone contradicts, checked when the spec arrives (before any input is read):
// points without spec.point_dims, spec.input_bytes that is not a whole number of points, a
// preview for points. INVALID_ARGUMENT naming the field.
absl::Status CheckSpecIsConsistent(const v1::JobSpec& spec);

// What the spec and the payload's Draco header (and metadata, core/io/draco_peek.h)
// contradict, checked when the input is complete and before Accepted: a mesh job whose
// payload is not Draco data or is a point cloud, a sequential payload that names the face id
// attribute. The decoder still has the last word on everything else. INVALID_ARGUMENT with
// "input mesh: ..." saying what and where (the header's byte).
absl::Status CheckPayloadAgainstSpec(const v1::JobSpec& spec, std::string_view input);

}  // namespace mlclust::server

#endif  // MLCLUST_SERVER_JOB_RUNNER_H_
