// The clustered mesh a command writes (mesh --out, --ply; watch --ply), its format by the
// file's extension. Also linked into the Python package's helper library (python/draco_c.cc),
// so `mlclust.write_clustered` writes what the CLI writes.
#ifndef MLCLUST_CLIENT_CLUSTERED_MESH_FILE_H_
#define MLCLUST_CLIENT_CLUSTERED_MESH_FILE_H_

#include <optional>
#include <span>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "core/base/ids.h"
#include "core/mesh/mesh.h"

namespace mlclust::client {

enum class ClusteredMeshFormat {
  kPly,   // core/io's WriteClusteredPly: the int `cluster` face property and a colour per face
  kGltf,  // .glb / .gltf: core/io's WriteClusteredGltf, the `_CLUSTER` vertex attribute
  kObj,   // WriteClusteredObj: one group per run of faces of one cluster
};

// The format of `path` by its extension (case ignored): .ply, .glb, .gltf or .obj.
// INVALID_ARGUMENT naming `flag` ("--out"; may be empty) and the extensions it writes otherwise, so
// that a command refuses a name it cannot write before it runs a job.
absl::StatusOr<ClusteredMeshFormat> ClusteredMeshFormatOf(const std::string& flag,
                                                          const std::string& path);

// The checks of a command's clustered mesh outputs before it runs a job: `out` (--out) of a
// format ClusteredMeshFormatOf knows, and `ply` (--ply) a .ply name: a PLY file under a
// .glb name is refused, naming --out for the format the name asks for. INVALID_ARGUMENT
// naming the flag and the file.
absl::Status CheckClusteredMeshOutputs(const std::optional<std::string>& out,
                                       const std::optional<std::string>& ply);

// Writes `mesh` with one cluster id per face (ClusterId::Invalid(): none) in the format of
// `path`'s extension. Errors as ClusteredMeshFormatOf and the writer's.
absl::Status WriteClusteredMesh(const std::string& path, const TriangleMesh& mesh,
                                std::span<const ClusterId> labels);

// Writes `mesh` as Wavefront OBJ: the vertices as written ("%.9g": float32 exactly), then
// the faces in order, a line "g cluster_K" before each run of faces in cluster K
// ("g unclustered" for ClusterId::Invalid()); a cluster whose faces are not consecutive
// has its group name more than once, which OBJ readers join. Face f of the file is face f
// of `mesh`. INVALID_ARGUMENT for a label count other than one per face or a vertex index
// out of range; UNAVAILABLE if the file cannot be written.
absl::Status WriteClusteredObj(const std::string& path, const TriangleMesh& mesh,
                               std::span<const ClusterId> labels);

}  // namespace mlclust::client

#endif  // MLCLUST_CLIENT_CLUSTERED_MESH_FILE_H_
