// The commands of `mlclust` besides serve (client/serve_command.h) and watch, cancel, jobs
// (client/job_commands.h): each its command line (cli.h) and what runs it.
#ifndef MLCLUST_CLIENT_COMMANDS_H_
#define MLCLUST_CLIENT_COMMANDS_H_

#include "client/cli.h"

namespace mlclust::cli {

// `mlclust mesh INPUT ...` (mesh_command.cc): exit code 0; 2 for bad arguments; 1 when
// reading, the server or an output fails; 3 when --coarse's level has no coarse mesh (the
// other outputs written).
Command MeshCommand();
// `mlclust points INPUT ...` (points_command.cc).
Command PointsCommand();
// `mlclust energy INPUT --labels FILE`, `mlclust stats`, `mlclust info` (query_commands.cc).
Command EnergyCommand();
Command StatsCommand();
Command InfoCommand();

}  // namespace mlclust::cli

#endif  // MLCLUST_CLIENT_COMMANDS_H_
