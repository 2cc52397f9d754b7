// Cooperative cancellation of long library calls.
//
// Every option struct of a long-running call carries
//
//   const std::atomic<bool>* cancel = nullptr;
//
// The caller (the server's worker, a CLI signal handler) sets the flag from any thread;
// the call checks it at safe points (between sweeps, every few thousand merges or moves,
// between set-up stages) and returns absl::CancelledError, leaving its outputs unspecified.
// A null pointer means "never cancelled".
#ifndef MLCLUST_CORE_BASE_CANCEL_H_
#define MLCLUST_CORE_BASE_CANCEL_H_

#include <atomic>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"

namespace mlclust {

inline bool IsCancelled(const std::atomic<bool>* cancel) {
  return cancel != nullptr && cancel->load(std::memory_order_relaxed);
}

// OK, or CANCELLED naming `where` ("EMLO sweep 12", "ML level 5000").
inline absl::Status CheckCancelled(const std::atomic<bool>* cancel, absl::string_view where) {
  if (!IsCancelled(cancel)) return absl::OkStatus();
  return absl::CancelledError(absl::StrCat("cancelled during ", where));
}

}  // namespace mlclust

#endif  // MLCLUST_CORE_BASE_CANCEL_H_
