// The command line of `mlclust`: every command's flags as one table (rows of Flag), from
// which CLI11 registers the options and the help text is printed, so that what is parsed
// and what is documented cannot drift. The algorithms' options are rows made from the
// registry (core/cluster/registry.h), so the registry, the parser and the usage are one
// list. Also what the commands share: Fail (the exit code of a status) and JSON helpers.
#ifndef MLCLUST_CLIENT_CLI_H_
#define MLCLUST_CLIENT_CLI_H_

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/cluster/registry.h"
#include "google/protobuf/message.h"

namespace mlclust::cli {

// One option of a command: what CLI11 registers and what the help prints.
struct Flag {
  Flag(std::string name, std::string value, std::string help, char short_name = 0)
      : name(std::move(name)),
        value(std::move(value)),
        help(std::move(help)),
        short_name(short_name) {}
  std::string name;     // --name
  std::string value;    // "K", "FILE"; empty: a switch without a value
  std::string help;     // one paragraph, wrapped when printed
  char short_name = 0;  // -k, -o, -q
  std::string details;  // lines printed under the row as they are (the list of algorithms)
};

// Rows under one heading. `stacked`: the registry's style, the name on its own line and the
// help under it; else the name in a column and the help beside it.
struct FlagGroup {
  FlagGroup(std::string heading, std::vector<Flag> flags, bool stacked = false, bool shared = false)
      : heading(std::move(heading)), flags(std::move(flags)), stacked(stacked), shared(shared) {}
  std::string heading;  // "" : none
  std::vector<Flag> flags;
  bool stacked = false;
  bool shared = false;  // the connection flags: printed once in `mlclust help`
};

// What the command's help prints and what its parser accepts.
struct CommandLine {
  std::string name;         // "mesh"
  std::string synopsis;     // after "mlclust NAME", lines already indented
  std::string description;  // a paragraph, wrapped when printed
  std::vector<FlagGroup> groups;
};

// The values given on a command line.
class Arguments {
 public:
  bool has(const std::string& name) const { return values_.contains(name); }
  std::string get(const std::string& name, const std::string& fallback = "") const;
  std::optional<std::string> value(const std::string& name) const;
  // A non-negative integer up to `max` (a count that travels as uint32 on the wire is
  // refused above 2^32 - 1, never truncated).
  absl::StatusOr<uint64_t> GetUint(const std::string& name, uint64_t fallback,
                                   uint64_t max = UINT64_MAX) const;
  const std::vector<std::string>& positional() const { return positional_; }

  void Set(const std::string& name, const std::string& value) { values_[name] = value; }
  void AddPositional(const std::string& value) { positional_.push_back(value); }

 private:
  std::map<std::string, std::string> values_;
  std::vector<std::string> positional_;
};

// A command: its command line and what runs it (returns the exit code).
struct Command {
  CommandLine line;
  std::function<int(const Arguments&)> run;
};

// Parses `args` (the words after the command's name) with CLI11 against `command`'s rows
// and -h/--help. INVALID_ARGUMENT naming the flag: "unknown option --NAME", "--NAME needs a
// value", "--NAME takes no value".
absl::StatusOr<Arguments> ParseCommandLine(const CommandLine& command,
                                           const std::vector<std::string>& args);

// The command's help: "  mlclust NAME SYNOPSIS", the description, every group of rows
// (`with_shared`: also the shared groups).
std::string CommandUsage(const CommandLine& command, bool with_shared = true);
// The rows of `group` as the help prints them.
std::string GroupUsage(const FlagGroup& group);

// `text` in lines of at most 92 columns, each starting with `indent` spaces.
std::string Wrap(const std::string& text, size_t indent);

// The flags every command that talks to a server shares (client/job_commands.h reads them).
FlagGroup ConnectionFlags();

// The command line of a command that talks to a server: --server ADDR (`server_help`),
// the command's `rows`, then the connection flags.
CommandLine ServerCommandLine(std::string name, std::string synopsis, std::string description,
                              std::string server_help, std::vector<Flag> rows);

// Rows from the registry: --algo with its algorithms and --energy with its energies
// (`input`'s), each algorithm's options under a heading, and for meshes the energy options.
Flag AlgorithmFlag(InputKind input);
Flag EnergyFlag(InputKind input, const std::string& default_text, bool wire_only);
std::vector<FlagGroup> RegistryOptionGroups(InputKind input);
FlagGroup EnergyOptionGroup();

// The names of every registry option of `input` (each algorithm's own, and for meshes the
// energy options), once each.
std::vector<std::string> RegistryOptionNames(InputKind input);

// The candidate nearest to a mistyped `word` (edit distance, at most a third of its length
// and at least 1; the first on a tie), or nullopt where none is that near.
std::optional<std::string> DidYouMean(const std::string& word,
                                      const std::vector<std::string>& candidates);

// Prints "mlclust: MESSAGE" on stderr; the exit code: 2 for INVALID_ARGUMENT, else 1.
int Fail(const absl::Status& status);

// A JSON string literal; a number (null where not finite); a message as a JSON object with
// the proto's field names (snake_case), every scalar field included (default values too),
// integers of every width as numbers (unlike proto3's JSON mapping, which writes 64-bit
// ones as strings), enums by name, bytes in base64, unset messages left out.
std::string JsonString(absl::string_view text);
std::string JsonNumber(double value);
std::string MessageJson(const google::protobuf::Message& message);

}  // namespace mlclust::cli

#endif  // MLCLUST_CLIENT_CLI_H_
