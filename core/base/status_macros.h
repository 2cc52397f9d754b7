// Early returns for absl::Status and absl::StatusOr, the one set used everywhere (core, gpu,
// server, client). For .cc files and function bodies; they declare nothing at file scope.
#ifndef MLCLUST_CORE_BASE_STATUS_MACROS_H_
#define MLCLUST_CORE_BASE_STATUS_MACROS_H_

#include <utility>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

#define MLCLUST_STATUS_CONCAT_INNER(a, b) a##b
#define MLCLUST_STATUS_CONCAT(a, b) MLCLUST_STATUS_CONCAT_INNER(a, b)

// Returns the status of `expr` from the enclosing function unless it is OK.
#define MLCLUST_RETURN_IF_ERROR(expr)                                                        \
  do {                                                                                       \
    if (::absl::Status mlclust_status = (expr); !mlclust_status.ok()) return mlclust_status; \
  } while (false)

// `lhs = *expr` when the StatusOr `expr` is OK; otherwise returns its status. `lhs` may
// declare a variable (`MLCLUST_ASSIGN_OR_RETURN(auto mesh, ReadMesh(path));`).
#define MLCLUST_ASSIGN_OR_RETURN(lhs, expr) \
  MLCLUST_ASSIGN_OR_RETURN_IMPL(MLCLUST_STATUS_CONCAT(mlclust_status_or_, __LINE__), lhs, expr)
#define MLCLUST_ASSIGN_OR_RETURN_IMPL(tmp, lhs, expr) \
  auto tmp = (expr);                                  \
  if (!tmp.ok()) return std::move(tmp).status();      \
  lhs = *std::move(tmp)

#endif  // MLCLUST_CORE_BASE_STATUS_MACROS_H_
