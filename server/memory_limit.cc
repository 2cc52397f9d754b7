#include "server/memory_limit.h"

#include <fstream>
#include <sstream>

#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"

namespace mlclust::server {
namespace {

std::optional<std::string> ReadWord(const std::string& path) {
  std::ifstream in(path);
  std::string word;
  if (!(in >> word)) return std::nullopt;
  return word;
}

// A limit file's value: bytes, or nullopt for "max" or v1's "no limit" (a value near
// 2^63 rounded to the page size).
std::optional<uint64_t> ParseLimit(const std::string& word) {
  uint64_t bytes = 0;
  if (word == "max" || !absl::SimpleAtoi(word, &bytes)) return std::nullopt;
  if (bytes >= (uint64_t{1} << 62)) return std::nullopt;
  return bytes;
}

// The process's cgroup v2 path ("0::/some/group" in /proc/self/cgroup), or "".
std::string OwnGroup() {
  std::ifstream in("/proc/self/cgroup");
  std::string line;
  while (std::getline(in, line)) {
    if (absl::StartsWith(line, "0::")) return line.substr(3);
  }
  return "";
}

std::string MiB(uint64_t bytes) { return absl::StrCat(bytes >> 20, " MiB"); }

}  // namespace

MemoryNeeded MemoryNeededFor(const ServerOptions& options) {
  MemoryNeeded needed;
  needed.running_jobs =
      (1 + uint64_t{options.cpu_workers}) * options.max_input_bytes * kJobBytesPerInputByte;
  needed.queued_inputs = options.max_queued_input_bytes;
  needed.uploads = options.max_upload_bytes_in_flight;
  needed.unread_events = options.result_server_budget_bytes;
  needed.kept_results = options.kept_results_bytes;
  return needed;
}

std::optional<uint64_t> CgroupMemoryLimit(const std::string& root) {
  const std::string group = OwnGroup();
  for (const std::string& path :
       {absl::StrCat(root, group, "/memory.max"), absl::StrCat(root, "/memory.max"),
        absl::StrCat(root, "/memory/memory.limit_in_bytes")}) {
    if (std::optional<std::string> word = ReadWord(path)) return ParseLimit(*word);
  }
  return std::nullopt;
}

bool RunningJobsFit(const MemoryNeeded& needed, std::optional<uint64_t> limit) {
  return !limit.has_value() || needed.total() <= *limit;
}

absl::Status CheckMemoryFits(const MemoryNeeded& needed, std::optional<uint64_t> limit) {
  if (!limit.has_value() || needed.budgets() <= *limit) return absl::OkStatus();
  return absl::InvalidArgumentError(absl::StrCat(
      "the server's budgets take up to ", MiB(needed.budgets()), " but it is given ", MiB(*limit),
      " (its cgroup's memory limit, or --memory-limit-mb): queued inputs ",
      MiB(needed.queued_inputs), " (--max-queued-mb), uploads ", MiB(needed.uploads),
      " (--max-upload-mb), unread events ", MiB(needed.unread_events),
      " (--result-total-mb), kept results ", MiB(needed.kept_results),
      " (--kept-results-mb), the process ", MiB(needed.process), "; with the running jobs (",
      MiB(needed.running_jobs), ": (1 + --workers) x --max-input-mb x ", kJobBytesPerInputByte,
      ") ", MiB(needed.total()),
      "; lower those flags or raise the limit (mlclust serve FLAGS --memory-needed prints the "
      "figure for the manifests)"));
}

}  // namespace mlclust::server
