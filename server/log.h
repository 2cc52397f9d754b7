// Server log lines on stderr, one per event, with a UTC timestamp: text by default, or one
// JSON object per line (serve --log-format json) with the event's fields (job id, tenant,
// algorithm, sizes, durations, outcome) for log collectors.
#ifndef MLCLUST_SERVER_LOG_H_
#define MLCLUST_SERVER_LOG_H_

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>
#include <string_view>

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

// What is logged of one value a client sent (a label, tenant, peer, job id) and of one
// whole message or line, at most; the rest is cut (LogSafe).
inline constexpr size_t kLoggedValueBytes = 256;
inline constexpr size_t kLoggedLineBytes = 4096;

// `text` made safe to log, in either format: every control character (C0 including
// newline and tab, DEL, C1, so no ANSI escape and no forged line) and every byte that is
// not valid UTF-8 written as the four characters "\xNN" (C1 as "\u00NN"), and the result
// cut at `max_bytes` (on a character boundary) with "...[N bytes]" saying how long the
// original was. Valid UTF-8 text without controls comes back as it was. Every value a
// log line carries goes through it (LogLine, LogEvent).
inline std::string LogSafe(std::string_view text, size_t max_bytes = kLoggedValueBytes) {
  std::string out;
  out.reserve(std::min(text.size(), max_bytes) + 16);
  size_t i = 0;
  for (; i < text.size() && out.size() < max_bytes;) {
    const auto byte = static_cast<unsigned char>(text[i]);
    size_t length = byte < 0x80           ? 1
                    : (byte >> 5) == 0x6  ? 2
                    : (byte >> 4) == 0xe  ? 3
                    : (byte >> 3) == 0x1e ? 4
                                          : 0;
    uint32_t code = length == 1   ? byte
                    : length == 2 ? byte & 0x1f
                    : length == 3 ? byte & 0x0f
                                  : byte & 0x07;
    bool valid = length > 0 && i + length <= text.size();
    for (size_t k = 1; valid && k < length; ++k) {
      const auto next = static_cast<unsigned char>(text[i + k]);
      valid = (next & 0xc0) == 0x80;
      code = (code << 6) | (next & 0x3f);
    }
    // Overlong forms, surrogates and code points past U+10FFFF are not UTF-8 either.
    if (valid && ((length == 2 && code < 0x80) || (length == 3 && code < 0x800) ||
                  (length == 4 && (code < 0x10000 || code > 0x10ffff)) ||
                  (code >= 0xd800 && code <= 0xdfff))) {
      valid = false;
    }
    if (!valid) {
      absl::StrAppend(&out, "\\x", absl::Hex(byte, absl::kZeroPad2));
      ++i;
    } else if (code < 0x20 || code == 0x7f) {
      absl::StrAppend(&out, "\\x", absl::Hex(code, absl::kZeroPad2));
      ++i;
    } else if (code >= 0x80 && code < 0xa0) {
      absl::StrAppend(&out, "\\u00", absl::Hex(code, absl::kZeroPad2));
      i += length;
    } else {
      out.append(text.substr(i, length));
      i += length;
    }
  }
  if (i < text.size()) absl::StrAppend(&out, "...[", text.size(), " bytes]");
  return out;
}

// `text` as a JSON string literal (after LogSafe: no controls, valid UTF-8).
inline std::string JsonQuote(std::string_view text, size_t max_bytes = kLoggedValueBytes) {
  std::string out = "\"";
  for (char c : LogSafe(text, max_bytes)) {
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out + "\"";
}

// A free-text line: `{"time":..,"level":"info","event":"message","message":..}` in JSON. The
// message is made safe and cut at kLoggedLineBytes; a value a client sent should be passed through
// LogSafe first, so it is cut at kLoggedValueBytes.
template <typename... Args>
void LogLine(bool enabled, const Args&... args) {
  if (!enabled) return;
  const std::string message = LogSafe(absl::StrCat(args...), kLoggedLineBytes);
  const std::string line =
      JsonLogs() ? absl::StrCat("{\"time\":\"", LogTimestamp(),
                                "\",\"level\":\"info\",\"event\":\"message\",\"message\":",
                                JsonQuote(message, kLoggedLineBytes), "}\n")
                 : absl::StrCat(LogTimestamp(), " mlclust: ", message, "\n");
  std::fputs(line.c_str(), stderr);
}

// A structured event: its fields in JSON, or `text` (the same line LogLine would write).
class LogEvent {
 public:
  // `level`: "info", "warning" or "error" (JSON's "level" field).
  explicit LogEvent(const std::string& event, const char* level = "info") {
    json_ = absl::StrCat("{\"time\":\"", LogTimestamp(), "\",\"level\":\"", level,
                         "\",\"event\":", JsonQuote(event));
  }
  // A string value: made safe and cut at `max_bytes` (a client's value at
  // kLoggedValueBytes, a message at kLoggedLineBytes).
  LogEvent& Add(const std::string& key, std::string_view value,
                size_t max_bytes = kLoggedValueBytes) {
    absl::StrAppend(&json_, ",", JsonQuote(key), ":", JsonQuote(value, max_bytes));
    return *this;
  }
  LogEvent& Add(const std::string& key, const char* value) {
    return Add(key, std::string_view(value));
  }
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
