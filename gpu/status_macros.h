// Early-return helpers for absl::Status in gpu/ sources (internal; not for headers that
// callers include). core/ has no such macros yet; these are local so that nothing outside
// gpu/ depends on them.
#ifndef MLCLUST_GPU_STATUS_MACROS_H_
#define MLCLUST_GPU_STATUS_MACROS_H_

#include "absl/status/status.h"
#include "absl/status/statusor.h"

#define MLCLUST_GPU_CONCAT_INNER(a, b) a##b
#define MLCLUST_GPU_CONCAT(a, b) MLCLUST_GPU_CONCAT_INNER(a, b)

// Returns the status of `expr` from the enclosing function unless it is OK.
#define MLCLUST_GPU_RETURN_IF_ERROR(expr)                    \
  do {                                                       \
    const absl::Status mlclust_gpu_status = (expr);          \
    if (!mlclust_gpu_status.ok()) return mlclust_gpu_status; \
  } while (false)

// `lhs = *expr` when the StatusOr `expr` is OK; otherwise returns its status.
#define MLCLUST_GPU_ASSIGN_OR_RETURN(lhs, expr) \
  MLCLUST_GPU_ASSIGN_OR_RETURN_IMPL(MLCLUST_GPU_CONCAT(mlclust_gpu_or_, __LINE__), lhs, expr)
#define MLCLUST_GPU_ASSIGN_OR_RETURN_IMPL(tmp, lhs, expr) \
  auto tmp = (expr);                                      \
  if (!tmp.ok()) return std::move(tmp).status();          \
  lhs = *std::move(tmp)

#endif  // MLCLUST_GPU_STATUS_MACROS_H_
