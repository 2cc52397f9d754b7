#include "client/cli.h"

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <iostream>

#include "absl/strings/escaping.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "google/protobuf/descriptor.h"

namespace mlclust::cli {
namespace {

constexpr size_t kWidth = 92;       // columns of the help text
constexpr size_t kHelpColumn = 25;  // where a row's help starts

// "a|b|c", "N in [0, 1024]", "X in [0, 100]".
std::string OptionValueText(const OptionInfo& option) {
  switch (option.type) {
    case OptionInfo::Type::kChoice:
      return absl::StrJoin(option.choices, "|");
    case OptionInfo::Type::kInteger:
      return absl::StrCat("N in [", static_cast<int64_t>(option.low), ", ",
                          static_cast<int64_t>(option.high), "]");
    case OptionInfo::Type::kNumber:
      return absl::StrCat("X in [", option.low, ", ", option.high, "]");
  }
  return "";
}

Flag RegistryFlag(const OptionInfo& option) {
  return {option.name, OptionValueText(option),
          absl::StrCat(option.help, " (default ", OptionDefaultNote(option), ")")};
}

// `text` wrapped to kWidth, the first line starting with `first` (padded to `indent`), the
// others with `indent` spaces.
std::string WrapAfter(const std::string& first, const std::string& text, size_t indent) {
  std::string out, line = first;
  if (line.size() < indent) line.resize(indent, ' ');
  bool empty = true;  // no word on `line` yet
  for (absl::string_view word : absl::StrSplit(text, ' ', absl::SkipEmpty())) {
    if (!empty && line.size() + 1 + word.size() > kWidth) {
      absl::StrAppend(&out, line, "\n");
      line.assign(indent, ' ');
      empty = true;
    }
    absl::StrAppend(&line, empty || line.back() == ' ' ? "" : " ", word);
    empty = false;
  }
  return absl::StrCat(out, line, "\n");
}

std::string FlagHead(const Flag& flag) {
  return absl::StrCat(
      flag.short_name != 0 ? absl::StrCat("-", std::string(1, flag.short_name), ", ") : "", "--",
      flag.name, flag.value.empty() ? "" : " ", flag.value);
}

}  // namespace

std::string Arguments::get(const std::string& name, const std::string& fallback) const {
  auto it = values_.find(name);
  return it == values_.end() ? fallback : it->second;
}

std::optional<std::string> Arguments::value(const std::string& name) const {
  auto it = values_.find(name);
  if (it == values_.end()) return std::nullopt;
  return it->second;
}

absl::StatusOr<uint64_t> Arguments::GetUint(const std::string& name, uint64_t fallback,
                                            uint64_t max) const {
  if (!has(name)) return fallback;
  uint64_t value;
  if (!absl::SimpleAtoi(get(name), &value)) {
    return absl::InvalidArgumentError(
        absl::StrCat("--", name, ": '", get(name), "' is not a non-negative integer"));
  }
  if (value > max) {
    return absl::InvalidArgumentError(
        absl::StrCat("--", name, ": ", value, " is over the largest accepted, ", max));
  }
  return value;
}

absl::StatusOr<Arguments> ParseCommandLine(const CommandLine& command,
                                           const std::vector<std::string>& args) {
  CLI::App app(command.name);
  app.set_help_flag();  // ours (-h, --help) is a row like the others: the help is ours
  app.allow_extras();   // named below as "unknown option"
  std::map<std::string, CLI::Option*> options;
  std::map<std::string, std::string> values;  // stable addresses for CLI11 to write to
  auto add = [&](const Flag& flag) {
    if (options.contains(flag.name)) return;  // a registry option several algorithms share
    std::string names = absl::StrCat("--", flag.name);
    if (flag.short_name != 0)
      names = absl::StrCat("-", std::string(1, flag.short_name), ",", names);
    options[flag.name] = flag.value.empty()
                             ? app.add_flag(names)->disable_flag_override()
                             : app.add_option(names, values[flag.name])
                                   ->type_name(flag.value)
                                   ->multi_option_policy(CLI::MultiOptionPolicy::TakeLast);
  };
  add({"help", "", "", 'h'});
  for (const FlagGroup& group : command.groups) {
    for (const Flag& flag : group.flags) add(flag);
  }
  std::vector<std::string> positional;
  app.add_option("arguments", positional);
  for (const std::string& arg : args) {
    // CLI11 takes the next word as the value of `--name=` (empty after '='); we refuse it
    // instead, so `--labels= --ply out.ply` does not write the labels to a file "--ply".
    if (arg.size() > 3 && arg.starts_with("--") && arg.back() == '=' &&
        arg.find('=') == arg.size() - 1) {
      return absl::InvalidArgumentError(
          absl::StrCat(arg.substr(0, arg.size() - 1), " needs a value"));
    }
  }
  std::vector<std::string> reversed(args.rbegin(), args.rend());  // CLI11 pops from the back
  try {
    app.parse(reversed);
  } catch (const CLI::ArgumentMismatch& e) {
    // "--deadline: 1 required SECONDS missing": the value was left out.
    const std::string what = e.what();
    const std::string name = what.substr(0, what.find(':'));
    if (absl::StrContains(what, "missing")) {
      return absl::InvalidArgumentError(absl::StrCat(name, " needs a value"));
    }
    if (absl::StrContains(what, "flag override")) {
      // "quiet was given a disallowed flag override": --quiet=yes.
      return absl::InvalidArgumentError(
          absl::StrCat("--", what.substr(0, what.find(' ')), " takes no value"));
    }
    return absl::InvalidArgumentError(what);
  } catch (const CLI::ParseError& e) {
    return absl::InvalidArgumentError(e.what());
  }
  for (const std::string& extra : app.remaining()) {
    const std::string name = extra.substr(0, extra.find('='));
    std::vector<std::string> known;
    known.reserve(options.size());
    for (const auto& [option, unused] : options) known.push_back(absl::StrCat("--", option));
    const std::optional<std::string> nearest = DidYouMean(name, known);
    return absl::InvalidArgumentError(
        absl::StrCat("unknown option ", name,
                     nearest.has_value() ? absl::StrCat("; did you mean ", *nearest, "?") : "",
                     " (`mlclust ", command.name, " --help` lists them)"));
  }
  Arguments parsed;
  for (const auto& [name, option] : options) {
    if (option->count() > 0) parsed.Set(name, values[name]);
  }
  for (const std::string& word : positional) parsed.AddPositional(word);
  return parsed;
}

std::optional<std::string> DidYouMean(const std::string& word,
                                      const std::vector<std::string>& candidates) {
  // Levenshtein distance, one row at a time.
  const auto distance = [](const std::string& a, const std::string& b) {
    std::vector<size_t> row(b.size() + 1);
    for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
    for (size_t i = 1; i <= a.size(); ++i) {
      size_t diagonal = row[0];
      row[0] = i;
      for (size_t j = 1; j <= b.size(); ++j) {
        const size_t above = row[j];
        row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
        diagonal = above;
      }
    }
    return row[b.size()];
  };
  const size_t limit = std::max<size_t>(1, word.size() / 3);
  std::optional<std::string> best;
  size_t best_distance = limit + 1;
  for (const std::string& candidate : candidates) {
    const size_t d = distance(word, candidate);
    if (d < best_distance) {
      best_distance = d;
      best = candidate;
    }
  }
  return best;
}

std::string Wrap(const std::string& text, size_t indent) {
  return WrapAfter(std::string(indent, ' '), text, indent);
}

std::string GroupUsage(const FlagGroup& group) {
  std::string out = group.heading.empty() ? "" : Wrap(group.heading, 4);
  for (const Flag& flag : group.flags) {
    if (group.stacked) {
      absl::StrAppend(&out, "        ", FlagHead(flag), "\n", Wrap(flag.help, 10));
    } else {
      std::string head = absl::StrCat("      ", FlagHead(flag));
      if (head.size() + 2 > kHelpColumn) {
        absl::StrAppend(&out, head, "\n");
        head.clear();
      }
      absl::StrAppend(&out, WrapAfter(head, flag.help, kHelpColumn));
    }
    absl::StrAppend(&out, flag.details);
  }
  return out;
}

std::string CommandUsage(const CommandLine& command, bool with_shared) {
  std::string out = absl::StrCat("\n  mlclust ", command.name, " ", command.synopsis, "\n");
  for (absl::string_view paragraph : absl::StrSplit(command.description, '\n')) {
    absl::StrAppend(&out, Wrap(std::string(paragraph), 6));
  }
  for (const FlagGroup& group : command.groups) {
    if (group.shared && !with_shared) continue;
    absl::StrAppend(&out, GroupUsage(group));
  }
  return out;
}

FlagGroup ConnectionFlags() {
  return {"connection flags (with --server):",
          {{"deadline", "SECONDS",
            "the call's deadline: a job still running then is cancelled (watch: the watch "
            "stops, the job runs on)"},
           {"tls-ca", "FILE", "TLS: the CA certificate (PEM) that signed the server's"},
           {"tls-cert", "FILE", "TLS: a client certificate, for servers that check them"},
           {"tls-key", "FILE", "TLS: the client certificate's key (with --tls-cert)"},
           {"auth-token-file", "F", "send the bearer token in F (its first word; needs TLS)"},
           {"spread", "least-loaded|in-order",
            "several servers: --server A:PORT,B:PORT,... or --server dns:///NAME:PORT (every "
            "address the name resolves to) spreads jobs over the replicas, the least loaded "
            "first (GetStats: queue depth plus running jobs; ties at random; the default), or "
            "in the order given. A replica that is unreachable, draining or full BEFORE it "
            "accepted the job is skipped and the job tried on the next. A replica lost AFTER "
            "accepting it (killed, drained with the job running): see --resubmit. A detached "
            "job's id names its replica (HOST:PORT/JOBID): watch and cancel go there; "
            "replicas share nothing, so a detached job lost with its replica is submitted "
            "again by running its command again (the same levels)."},
           {"resubmit", "N",
            "several servers: a job whose replica was lost after accepting it (unreachable, "
            "died, drained with the job; not a job that failed or was cancelled there, nor "
            "--deadline) is submitted again to the next replica, at most N times (default "
            "2; 0: never), a line on stderr each time. A job is a pure function of its "
            "input and options (seed included), so its levels are the same: those already "
            "received are kept, checked against the new stream (the job fails if a replica "
            "sent other levels) and not written twice"}},
          /*stacked=*/false,
          /*shared=*/true};
}

CommandLine ServerCommandLine(std::string name, std::string synopsis, std::string description,
                              std::string server_help, std::vector<Flag> rows) {
  rows.insert(rows.begin(), Flag("server", "ADDR", std::move(server_help)));
  return {std::move(name),
          std::move(synopsis),
          std::move(description),
          {FlagGroup("", std::move(rows)), ConnectionFlags()}};
}

Flag AlgorithmFlag(InputKind input) {
  Flag flag{"algo", "ALGO", absl::StrCat("(default ", DefaultAlgorithm(input).name, ")")};
  for (const AlgorithmInfo& algorithm : Algorithms()) {
    if (algorithm.input != input) continue;
    absl::StrAppend(&flag.details, "        ", algorithm.name, ": ", algorithm.title, "\n",
                    Wrap(absl::StrCat(algorithm.help,
                                      algorithm.divisive    ? " [hierarchy from K down to one]"
                                      : algorithm.hierarchy ? " [hierarchy]"
                                      : algorithm.chooses_k ? " [from K = k_min, finds its own K]"
                                                            : " [one K]"),
                         10));
  }
  return flag;
}

Flag EnergyFlag(InputKind input, const std::string& default_text, bool wire_only) {
  Flag flag{"energy", "E", absl::StrCat("(default ", default_text, ")")};
  for (const EnergyInfo& energy : Energies()) {
    if (energy.input != input || (wire_only && energy.wire == 0)) continue;
    absl::StrAppend(&flag.details, "        ", energy.name, ":\n", Wrap(energy.help, 10));
  }
  return flag;
}

std::vector<FlagGroup> RegistryOptionGroups(InputKind input) {
  std::vector<FlagGroup> groups;
  for (const AlgorithmInfo& algorithm : Algorithms()) {
    if (algorithm.input != input) continue;
    FlagGroup group{
        absl::StrCat(algorithm.name, " (energies: ", absl::StrJoin(algorithm.energies, ", "), ")",
                     algorithm.options.empty() ? ": no options of its own" : " options:"),
        {},
        /*stacked=*/true};
    for (const OptionInfo& option : algorithm.options) group.flags.push_back(RegistryFlag(option));
    groups.push_back(std::move(group));
  }
  if (input == InputKind::kMesh) groups.push_back(EnergyOptionGroup());
  return groups;
}

FlagGroup EnergyOptionGroup() {
  FlagGroup group{"energy options (every mesh algorithm):", {}, /*stacked=*/true};
  for (const OptionInfo& option : EnergyOptions()) group.flags.push_back(RegistryFlag(option));
  return group;
}

std::vector<std::string> RegistryOptionNames(InputKind input) {
  std::vector<std::string> names;
  for (const FlagGroup& group : RegistryOptionGroups(input)) {
    for (const Flag& flag : group.flags) {
      if (std::find(names.begin(), names.end(), flag.name) == names.end()) {
        names.push_back(flag.name);
      }
    }
  }
  return names;
}

int Fail(const absl::Status& status) {
  std::cerr << "mlclust: " << status.message() << "\n";
  return status.code() == absl::StatusCode::kInvalidArgument ? 2 : 1;
}

std::string JsonString(absl::string_view text) {
  std::string out = "\"";
  for (char c : text) {
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\t':
        out += "\\t";
        break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          out += absl::StrFormat("\\u%04x", static_cast<unsigned char>(c));
        } else {
          out += c;
        }
    }
  }
  return out + "\"";
}

std::string JsonNumber(double value) {
  return std::isfinite(value) ? absl::StrFormat("%.17g", value) : "null";
}

namespace {

// One field's value (`index` of a repeated field) as JSON: integers of every width as JSON
// numbers (proto3's JSON mapping writes 64-bit ones as strings), enums by name.
std::string FieldValueJson(const google::protobuf::Message& message,
                           const google::protobuf::FieldDescriptor* field, int index,
                           size_t indent);

// Recursive over nested messages: the depth is the proto's nesting, fixed and small.
std::string MessageJsonAt(  // NOLINT(misc-no-recursion): the proto's nesting depth
    const google::protobuf::Message& message, size_t indent) {
  const google::protobuf::Descriptor* descriptor = message.GetDescriptor();
  const google::protobuf::Reflection* reflection = message.GetReflection();
  const std::string pad(indent + 2, ' ');
  std::vector<std::string> members;
  for (int i = 0; i < descriptor->field_count(); ++i) {
    const google::protobuf::FieldDescriptor* field = descriptor->field(i);
    std::string value;
    if (field->is_map()) {
      // map<string, V>: an object, as the JSON mapping writes it.
      std::vector<std::string> entries;
      for (int e = 0; e < reflection->FieldSize(message, field); ++e) {
        const google::protobuf::Message& entry = reflection->GetRepeatedMessage(message, field, e);
        const google::protobuf::FieldDescriptor* key = entry.GetDescriptor()->map_key();
        const std::string key_text = key->type() == google::protobuf::FieldDescriptor::TYPE_STRING
                                         ? entry.GetReflection()->GetString(entry, key)
                                         : FieldValueJson(entry, key, -1, 0);
        entries.push_back(absl::StrCat(
            JsonString(key_text), ": ",
            FieldValueJson(entry, entry.GetDescriptor()->map_value(), -1, indent + 2)));
      }
      value = absl::StrCat("{", absl::StrJoin(entries, ", "), "}");
    } else if (field->is_repeated()) {
      std::vector<std::string> items;
      items.reserve(reflection->FieldSize(message, field));
      for (int e = 0; e < reflection->FieldSize(message, field); ++e) {
        items.push_back(FieldValueJson(message, field, e, indent + 2));
      }
      value = absl::StrCat("[", absl::StrJoin(items, ", "), "]");
    } else {
      // Every scalar, set or not (as always_print_primitive_fields); a message or a oneof
      // member only where it is set.
      const bool presence =
          field->cpp_type() == google::protobuf::FieldDescriptor::CPPTYPE_MESSAGE ||
          field->containing_oneof() != nullptr;
      if (presence && !reflection->HasField(message, field)) continue;
      value = FieldValueJson(message, field, -1, indent + 2);
    }
    members.push_back(absl::StrCat(pad, JsonString(field->name()), ": ", value));
  }
  if (members.empty()) return "{}";
  return absl::StrCat("{\n", absl::StrJoin(members, ",\n"), "\n", std::string(indent, ' '), "}");
}

std::string FieldValueJson(  // NOLINT(misc-no-recursion): the proto's nesting depth
    const google::protobuf::Message& message, const google::protobuf::FieldDescriptor* field,
    int index, size_t indent) {
  const google::protobuf::Reflection* r = message.GetReflection();
  const bool one = index < 0;
  using Field = google::protobuf::FieldDescriptor;
  switch (field->cpp_type()) {
    case Field::CPPTYPE_INT32:
      return absl::StrCat(one ? r->GetInt32(message, field)
                              : r->GetRepeatedInt32(message, field, index));
    case Field::CPPTYPE_INT64:
      return absl::StrCat(one ? r->GetInt64(message, field)
                              : r->GetRepeatedInt64(message, field, index));
    case Field::CPPTYPE_UINT32:
      return absl::StrCat(one ? r->GetUInt32(message, field)
                              : r->GetRepeatedUInt32(message, field, index));
    case Field::CPPTYPE_UINT64:
      return absl::StrCat(one ? r->GetUInt64(message, field)
                              : r->GetRepeatedUInt64(message, field, index));
    case Field::CPPTYPE_DOUBLE:
      return JsonNumber(one ? r->GetDouble(message, field)
                            : r->GetRepeatedDouble(message, field, index));
    case Field::CPPTYPE_FLOAT: {
      const float value =
          one ? r->GetFloat(message, field) : r->GetRepeatedFloat(message, field, index);
      return std::isfinite(value) ? absl::StrFormat("%.9g", value) : "null";
    }
    case Field::CPPTYPE_BOOL:
      return (one ? r->GetBool(message, field) : r->GetRepeatedBool(message, field, index))
                 ? "true"
                 : "false";
    case Field::CPPTYPE_ENUM: {
      const int number =
          one ? r->GetEnumValue(message, field) : r->GetRepeatedEnumValue(message, field, index);
      const google::protobuf::EnumValueDescriptor* value =
          field->enum_type()->FindValueByNumber(number);
      return value != nullptr ? JsonString(value->name()) : absl::StrCat(number);
    }
    case Field::CPPTYPE_STRING: {
      const std::string text =
          one ? r->GetString(message, field) : r->GetRepeatedString(message, field, index);
      return JsonString(field->type() == Field::TYPE_BYTES ? absl::Base64Escape(text) : text);
    }
    case Field::CPPTYPE_MESSAGE:
      return MessageJsonAt(
          one ? r->GetMessage(message, field) : r->GetRepeatedMessage(message, field, index),
          indent);
  }
  return "null";
}

}  // namespace

std::string MessageJson(const google::protobuf::Message& message) {
  return absl::StrCat(MessageJsonAt(message, 0), "\n");
}

}  // namespace mlclust::cli
