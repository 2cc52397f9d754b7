// Server log lines on stderr, one per event, with a UTC timestamp.
#ifndef MLCLUST_SERVER_LOG_H_
#define MLCLUST_SERVER_LOG_H_

#include <cstdio>
#include <string>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"

namespace mlclust::server {

template <typename... Args>
void LogLine(bool enabled, const Args&... args) {
  if (!enabled) return;
  const std::string line =
      absl::StrCat(absl::FormatTime("%Y-%m-%dT%H:%M:%E3SZ", absl::Now(), absl::UTCTimeZone()),
                   " mlclust: ", args..., "\n");
  std::fputs(line.c_str(), stderr);
}

}  // namespace mlclust::server

#endif  // MLCLUST_SERVER_LOG_H_
