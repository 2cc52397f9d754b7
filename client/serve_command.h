// `mlclust serve`: runs the gRPC server until SIGINT or SIGTERM. Owns its flags and usage
// text; client/main.cc only dispatches to it.
#ifndef MLCLUST_CLIENT_SERVE_COMMAND_H_
#define MLCLUST_CLIENT_SERVE_COMMAND_H_

namespace mlclust::cli {

// The usage lines of `serve` (part of `mlclust help`, and `mlclust serve --help`).
const char* ServeUsage();

// Runs `mlclust serve` with the arguments after "serve" (argv[0] is the first flag).
// Returns the process exit code: 0 after a clean shutdown, 2 for a bad flag, 1 when the
// server cannot start.
int RunServeCommand(int argc, char** argv);

}  // namespace mlclust::cli

#endif  // MLCLUST_CLIENT_SERVE_COMMAND_H_
