// mlclust: the command-line client. See `mlclust help`. Each command's flags are rows of its
// command line (client/cli.h), parsed by CLI11 and printed as its help; this file only
// dispatches.
#include <cstdio>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "client/cli.h"
#include "client/commands.h"
#include "client/job_commands.h"
#include "client/serve_command.h"
#include "server/job_options.h"
#include "server/server.h"

namespace mlclust::cli {
namespace {

constexpr char kTitle[] = R"(mlclust — multilevel clustering of meshes and point sets

usage:
)";

constexpr char kGeneral[] = R"(
  mlclust --version | help [COMMAND] | COMMAND --help
      -k K is --clusters K, -o FILE is --labels FILE, -q is --quiet; --json prints the job
      summary of mesh and points as one JSON object. Exit codes: 0 done, 2 a bad argument,
      1 a failure (reading, the server, an output), 3 mesh --coarse's level has no coarse
      mesh (the other outputs written).
)";

const std::vector<Command>& Commands() {
  static const auto* commands = new std::vector<Command>{
      ServeCommand(), MeshCommand(),  PointsCommand(), EnergyCommand(), StatsCommand(),
      InfoCommand(),  WatchCommand(), CancelCommand(), JobsCommand()};
  return *commands;
}

const Command* FindCommand(const std::string& name) {
  for (const Command& command : Commands()) {
    if (command.line.name == name) return &command;
  }
  return nullptr;
}

std::string CommandNames() {
  std::string names;
  for (const Command& command : Commands()) {
    absl::StrAppend(&names, names.empty() ? "" : ", ", command.line.name);
  }
  return names;
}

// Every command's usage; the connection flags they share once, at the end.
void PrintUsage(std::FILE* out) {
  std::fputs(kTitle, out);
  for (const Command& command : Commands()) {
    std::fputs(CommandUsage(command.line, /*with_shared=*/false).c_str(), out);
  }
  std::fputs(kGeneral, out);
  std::fputs(absl::StrCat("\n", GroupUsage(ConnectionFlags())).c_str(), out);
}

int Main(int argc, char** argv) {
  if (argc < 2) {
    PrintUsage(stderr);
    return 2;
  }
  const std::string name = argv[1];
  if (name == "--version" || name == "version") {
    std::printf("mlclust %s\n", server::kMlclustVersion);
    return 0;
  }
  if (name == "help" || name == "--help" || name == "-h") {
    // `mlclust help CMD`: that command's usage; `mlclust help`: all of it.
    if (argc < 3) {
      PrintUsage(stdout);
      return 0;
    }
    const Command* command = FindCommand(argv[2]);
    if (command == nullptr) {
      std::fprintf(stderr, "mlclust: no command '%s'; the commands: %s\n", argv[2],
                   CommandNames().c_str());
      return 2;
    }
    std::fputs(CommandUsage(command->line).c_str(), stdout);
    return 0;
  }
  const Command* command = FindCommand(name);
  if (command == nullptr) {
    std::fprintf(stderr, "mlclust: unknown command '%s'\n\n", name.c_str());
    PrintUsage(stderr);
    return 2;
  }
  absl::StatusOr<Arguments> args =
      ParseCommandLine(command->line, std::vector<std::string>(argv + 2, argv + argc));
  if (!args.ok()) return Fail(args.status());
  if (args->has("help")) {
    std::fputs(CommandUsage(command->line).c_str(), stdout);
    return 0;
  }
  return command->run(*args);
}

}  // namespace
}  // namespace mlclust::cli

int main(int argc, char** argv) { return mlclust::cli::Main(argc, argv); }
