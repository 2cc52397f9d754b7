// `mlclust mesh INPUT --meshlets FILE`: capped meshlets (core/meshlets/meshlets.h) written as
// the meshlet file (core/meshlets/meshlet_file.h). They are built here, in the client, from
// the mesh as read: no job is sent (the server has no meshlet message yet).
#ifndef MLCLUST_CLIENT_MESHLETS_COMMAND_H_
#define MLCLUST_CLIENT_MESHLETS_COMMAND_H_

#include <vector>

#include "client/cli.h"

namespace mlclust::cli {

// The rows `mlclust mesh` adds for meshlets: --meshlets, --max-vertices, --max-triangles,
// --cone-weight.
std::vector<Flag> MeshletFlags();

// Runs the meshlet mode of `mlclust mesh` (args has "meshlets"): exit code 0; 2 for bad
// arguments (a flag of the clustering job beside --meshlets, caps out of range); 1 when
// reading the mesh or writing an output fails. --labels writes each face's meshlet.
int RunMeshMeshlets(const Arguments& args);

}  // namespace mlclust::cli

#endif  // MLCLUST_CLIENT_MESHLETS_COMMAND_H_
