// What the bench mains share: `--name value` arguments, wall-clock timing, mesh set-up and
// point files.
//
//   bench::Args args(argc, argv, "usage: mesh_bench MESH --k K [--algo emlo|bb] ...");
//   const bool header = args.Flag("header");      // flags first (see Flag)
//   const std::string path = args.Positional(0);
//   const uint32_t k = args.Get<uint32_t>("k", 1000);
//   if (!args.Done()) return 2;   // unknown or malformed options, printed with the usage
//   const mlclust::PreparedMesh mesh = bench::PrepareOrDie(path);
//
// Each main still prints its own CSV row: what a bench measures is its own business.
#ifndef MLCLUST_BENCH_BENCH_UTIL_H_
#define MLCLUST_BENCH_BENCH_UTIL_H_

#include <cstdio>
#include <cstdlib>
#include <limits>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_split.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "core/io/points_io.h"
#include "core/io/prepare_mesh.h"

namespace mlclust::bench {

// `--name value` options, `--name` flags and positional arguments. Get/Flag mark an
// option as known; Done() reports anything left unknown or unparsable (with the usage).
class Args {
 public:
  Args(int argc, char** argv, std::string usage) : usage_(std::move(usage)) {
    for (int i = 1; i < argc; ++i) {
      std::string_view arg = argv[i];
      if (arg.size() > 2 && arg.substr(0, 2) == "--") {
        Entry entry{std::string(arg.substr(2)), "", false, false};
        if (i + 1 < argc && std::string_view(argv[i + 1]).substr(0, 2) != "--") {
          entry.value = argv[++i];
          entry.has_value = true;
        }
        options_.push_back(std::move(entry));
      } else {
        positional_.emplace_back(arg);
      }
    }
  }

  // The i-th positional argument, or "" (then Done() fails) if there is none.
  std::string Positional(size_t i) {
    if (i < positional_.size()) return positional_[i];
    errors_ += "missing positional argument " + std::to_string(i + 1) + "\n";
    return "";
  }
  size_t num_positional() const { return positional_.size(); }

  // An optional positional argument: the i-th one parsed as T (integers, double,
  // std::string), or `fallback` if there is none; Done() fails if it does not parse.
  template <typename T>
  T Positional(size_t i, T fallback) {
    if (i >= positional_.size()) return fallback;
    T value = fallback;
    if (!Parse(positional_[i], value)) {
      errors_ += "positional argument " + std::to_string(i + 1) + ": cannot parse '" +
                 positional_[i] + "'\n";
    }
    return value;
  }

  // The value of --name, parsed as T (integers, double, std::string), or `fallback`.
  template <typename T>
  T Get(std::string_view name, T fallback) {
    Entry* entry = Find(name);
    if (entry == nullptr) return fallback;
    entry->used = true;
    if (!entry->has_value) {
      errors_ += "--" + entry->name + " needs a value\n";
      return fallback;
    }
    T value = fallback;
    if (!Parse(entry->value, value)) {
      errors_ += "--" + entry->name + ": cannot parse '" + entry->value + "'\n";
    }
    return value;
  }

  // The value of --name as a comma-separated list ("1000,200"), each item parsed as T, or
  // `fallback` (the same kind of list; "" for none) if --name is not given; Done() fails if
  // an item does not parse.
  template <typename T>
  std::vector<T> GetList(std::string_view name, std::string_view fallback) {
    const std::string text = Get<std::string>(name, std::string(fallback));
    std::vector<T> values;
    if (text.empty()) return values;
    for (absl::string_view item : absl::StrSplit(text, ',')) {
      T value{};
      if (!Parse(std::string(item), value)) {
        errors_ += "--" + std::string(name) + ": '" + text + "' is not a list of numbers\n";
        return {};
      }
      values.push_back(value);
    }
    return values;
  }

  // Whether the flag --name was given (a flag takes no value). The parser cannot tell a
  // flag from an option, so a word after a flag is first taken as its value and given back
  // here: ask for every flag before the positional arguments.
  bool Flag(std::string_view name) {
    Entry* entry = Find(name);
    if (entry == nullptr) return false;
    entry->used = true;
    if (entry->has_value) {
      // A flag followed by a positional argument: give the argument back.
      positional_.push_back(entry->value);
      entry->has_value = false;
    }
    return true;
  }

  // True if every option was known and parsed; otherwise prints the problems and the
  // usage to stderr.
  bool Done() {
    for (const Entry& entry : options_) {
      if (!entry.used) errors_ += "unknown option --" + entry.name + "\n";
    }
    if (errors_.empty()) return true;
    std::fprintf(stderr, "%s%s\n", errors_.c_str(), usage_.c_str());
    return false;
  }

 private:
  struct Entry {
    std::string name, value;
    bool has_value, used;
  };
  Entry* Find(std::string_view name) {
    for (Entry& entry : options_) {
      if (entry.name == name) return &entry;
    }
    return nullptr;
  }
  static bool Parse(const std::string& text, std::string& out) {
    out = text;
    return true;
  }
  static bool Parse(const std::string& text, double& out) { return absl::SimpleAtod(text, &out); }
  template <typename Int>
  static bool Parse(const std::string& text, Int& out) {
    return absl::SimpleAtoi(text, &out);
  }

  std::string usage_, errors_;
  std::vector<Entry> options_;
  std::vector<std::string> positional_;
};

// Wall-clock seconds since construction (or the last Restart).
class Stopwatch {
 public:
  Stopwatch() : start_(absl::Now()) {}
  void Restart() { start_ = absl::Now(); }
  double Seconds() const { return absl::ToDoubleSeconds(absl::Now() - start_); }

 private:
  absl::Time start_;
};

// The smallest of `repeats` timings of `run()` (seconds), `run` returning whether it
// worked; a negative result if any run failed.
template <typename Run>
double BestOf(int repeats, Run&& run) {
  double best = std::numeric_limits<double>::infinity();
  for (int r = 0; r < repeats; ++r) {
    Stopwatch watch;
    if (!run()) return -1;
    best = std::min(best, watch.Seconds());
  }
  return best;
}

// The value of `result`, or its status on stderr and exit(1): a bench has nothing to do
// after a step that failed.
template <typename T>
T ValueOrDie(absl::StatusOr<T> result) {
  if (!result.ok()) {
    std::fprintf(stderr, "%s\n", result.status().ToString().c_str());
    std::exit(1);
  }
  return *std::move(result);
}

// PrepareMeshFile, or a message on stderr and exit(1): benches have nothing to do
// without their mesh.
inline PreparedMesh PrepareOrDie(const std::string& path) {
  absl::StatusOr<PreparedMesh> prepared = PrepareMeshFile(path);
  if (!prepared.ok()) {
    std::fprintf(stderr, "%s: %s\n", path.c_str(), prepared.status().ToString().c_str());
    std::exit(1);
  }
  return *std::move(prepared);
}

// ReadPointsFile (with `dims` values per point; 0: from the file), or a message on stderr
// and exit(1), as PrepareOrDie.
inline PointSet ReadPointsOrDie(const std::string& path, uint32_t dims = 0) {
  PointReadOptions options;
  options.dims = dims;
  absl::StatusOr<PointSet> points = ReadPointsFile(path, options);
  if (!points.ok()) {
    std::fprintf(stderr, "%s: %s\n", path.c_str(), points.status().ToString().c_str());
    std::exit(1);
  }
  return *std::move(points);
}

// The file name without directories ("data/bench/armadillo.off" -> "armadillo.off").
inline std::string BaseName(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  return slash == std::string::npos ? path : path.substr(slash + 1);
}

}  // namespace mlclust::bench

#endif  // MLCLUST_BENCH_BENCH_UTIL_H_
