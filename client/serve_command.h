// `mlclust serve`: runs the gRPC server until SIGINT or SIGTERM. Owns its flags (the rows
// of its command line) and what runs them; client/main.cc only dispatches to it.
#ifndef MLCLUST_CLIENT_SERVE_COMMAND_H_
#define MLCLUST_CLIENT_SERVE_COMMAND_H_

#include "client/cli.h"

namespace mlclust::cli {

// `mlclust serve`: exit code 0 after a clean shutdown, 2 for a bad flag, 1 when the server
// cannot start.
Command ServeCommand();

}  // namespace mlclust::cli

#endif  // MLCLUST_CLIENT_SERVE_COMMAND_H_
