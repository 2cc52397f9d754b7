// What every GPU pass does around its work: a name for its errors, and the test hook that
// injects a real GL failure into it.
//
// A pass is one step of a GPU stage ("cluster sums", "bb decide", "ln-kmeans assign",
// ...). Its errors reach the job as they are, prefixed with the pass's name, so a job that
// fails on the GPU says where: "GPU pass 'bb decide': glDispatchCompute failed:
// GL_INVALID_VALUE". A pass that fails never falls back to the CPU by itself (issue 10: a
// fallback is chosen at plan time or not at all).
//
// Fault injection (for tests of the error path, never for production): with the
// environment variable MLCLUST_GPU_FAIL_PASS set to a pass's name (or "*" for every pass),
// BeginPass issues an invalid GL call (glBindBufferBase with binding point 2^32 - 1), so
// the pass meets a real GL_INVALID_VALUE at its next error check and fails with INTERNAL
// through the same path a driver error takes. The variable is read at every BeginPass, so
// a test can set and clear it between jobs of one server.
#ifndef MLCLUST_GPU_CONTEXT_PASS_H_
#define MLCLUST_GPU_CONTEXT_PASS_H_

#include "absl/status/status.h"
#include "absl/strings/string_view.h"
#include "gpu/context/gl_context.h"

namespace mlclust::gpu {

// The environment variable of the fault injection hook.
inline constexpr char kFailPassVariable[] = "MLCLUST_GPU_FAIL_PASS";

// Makes `context` current (FAILED_PRECONDITION on another thread) and clears stale GL
// errors; then, if MLCLUST_GPU_FAIL_PASS names `pass` (or is "*"), injects a GL error.
absl::Status BeginPass(GlContext& context, absl::string_view pass);

// `status` with "GPU pass 'PASS': " before its message (OK stays OK); the code is kept.
absl::Status PassError(absl::string_view pass, const absl::Status& status);

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_CONTEXT_PASS_H_
