// Server log lines on stderr, one per event, with a UTC timestamp: text by default, or one
// JSON object per line (serve --log-format json) with the event's fields (job id, tenant,
// algorithm, sizes, durations, outcome) for log collectors.
#ifndef MLCLUST_SERVER_LOG_H_
#define MLCLUST_SERVER_LOG_H_

#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"

namespace mlclust::server {

// Process-wide: JSON lines instead of text (set by Server::Start from its options).
inline std::atomic<bool>& JsonLogs() {
  static std::atomic<bool> json{false};
  return json;
}

inline std::string LogTimestamp() {
  return absl::FormatTime("%Y-%m-%dT%H:%M:%E3SZ", absl::Now(), absl::UTCTimeZone());
}

// `text` as a JSON string literal.
inline std::string JsonQuote(const std::string& text) {
  std::string out = "\"";
  for (unsigned char c : text) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += static_cast<char>(c);
    } else if (c < 0x20) {
      out += absl::StrFormat("\\u%04x", c);
    } else {
      out += static_cast<char>(c);
    }
  }
  return out + "\"";
}

// A free-text line: `{"time":..,"event":"message","message":..}` in JSON.
template <typename... Args>
void LogLine(bool enabled, const Args&... args) {
  if (!enabled) return;
  const std::string message = absl::StrCat(args...);
  const std::string line =
      JsonLogs() ? absl::StrCat("{\"time\":\"", LogTimestamp(),
                                "\",\"event\":\"message\",\"message\":", JsonQuote(message), "}\n")
                 : absl::StrCat(LogTimestamp(), " mlclust: ", message, "\n");
  std::fputs(line.c_str(), stderr);
}

// A structured event: its fields in JSON, or `text` (the same line LogLine would write).
class LogEvent {
 public:
  explicit LogEvent(const std::string& event) {
    json_ = absl::StrCat("{\"time\":\"", LogTimestamp(), "\",\"event\":", JsonQuote(event));
  }
  LogEvent& Add(const std::string& key, const std::string& value) {
    absl::StrAppend(&json_, ",", JsonQuote(key), ":", JsonQuote(value));
    return *this;
  }
  LogEvent& Add(const std::string& key, const char* value) { return Add(key, std::string(value)); }
  LogEvent& Add(const std::string& key, uint64_t value) {
    absl::StrAppend(&json_, ",", JsonQuote(key), ":", value);
    return *this;
  }
  LogEvent& Add(const std::string& key, int value) {
    absl::StrAppend(&json_, ",", JsonQuote(key), ":", value);
    return *this;
  }
  LogEvent& Add(const std::string& key, bool value) {
    absl::StrAppend(&json_, ",", JsonQuote(key), ":", value ? "true" : "false");
    return *this;
  }
  LogEvent& Add(const std::string& key, double value) {
    absl::StrAppend(&json_, ",", JsonQuote(key), ":",
                    std::isfinite(value) ? absl::StrFormat("%.6f", value) : std::string("null"));
    return *this;
  }
  void Write(bool enabled, const std::string& text) const {
    if (!enabled) return;
    if (!JsonLogs()) {
      LogLine(true, text);
      return;
    }
    const std::string line = absl::StrCat(json_, "}\n");
    std::fputs(line.c_str(), stderr);
  }

 private:
  std::string json_;
};

}  // namespace mlclust::server

#endif  // MLCLUST_SERVER_LOG_H_
