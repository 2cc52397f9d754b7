#include "client/meshlets_command.h"

#include <algorithm>
#include <cstdio>
#include <string>

#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "client/job_cli.h"
#include "core/io/mesh_io.h"
#include "core/meshlets/meshlet_file.h"
#include "core/meshlets/meshlet_gltf.h"
#include "core/meshlets/meshlets.h"

namespace mlclust::cli {

std::vector<Flag> MeshletFlags() {
  return {{"meshlets", "FILE",
           "instead of clustering: cut the mesh into meshlets a mesh shader can draw, at most "
           "--max-vertices vertices and --max-triangles triangles each, every one edge-connected "
           "(ours; core/meshlets/meshlets.h), with each meshlet's bounding sphere and normal cone "
           "(meshoptimizer's meshopt_computeMeshletBounds), and write them to FILE; --labels then "
           "writes each face's meshlet. Built in this process from the mesh as read (no job is "
           "sent). FILE is little-endian: a 64-byte header (magic \"MLCMSHLT\", uint32 version 1, "
           "header bytes 64, max_vertices, max_triangles, meshlet count M, vertex entries N, "
           "triangle bytes B, faces F, vertices V, flags (1: bounds)), then M meshlets of 4 "
           "uint32 (vertex_offset, triangle_offset in bytes, vertex_count, triangle_count: "
           "meshoptimizer's meshopt_Meshlet), N uint32 vertex indices, B bytes of local indices (3 "
           "per triangle, each meshlet's run padded to 4 bytes), F uint32 faces (the input face of "
           "each meshlet triangle, in order), and M bounds of 48 bytes (centre xyz, radius, cone "
           "apex xyz, cone axis xyz, cone cutoff as float32; cone axis xyz and cutoff as int8 "
           "SNORM). FILE.glb instead: a glTF 2.0 binary with the mesh (its index buffer in meshlet "
           "order) and the same arrays as buffer views, named in the mesh's "
           "extras.mlclust_meshlets (core/meshlets/meshlet_gltf.h)"},
          {"max-vertices", "N",
           "with --meshlets: distinct vertices per meshlet, 3 to 255 (default 64)"},
          {"max-triangles", "N", "with --meshlets: triangles per meshlet, 1 to 512 (default 124)"},
          {"cone-weight", "W",
           "with --meshlets: 0 to 1, how much normals count against distance while a meshlet "
           "grows (tighter cones, wider spheres; default 0, meshoptimizer's meaning)"}};
}

int RunMeshMeshlets(const Arguments& args) {
  if (args.positional().size() != 1) {
    return Fail(absl::InvalidArgumentError("mesh: give exactly one INPUT file"));
  }
  // Flags of the clustering job mean nothing here: say so rather than drop them.
  for (const char* job_flag : {"clusters", "auto-k", "ply", "coarse", "preview", "plot",
                               "levels-csv", "planar-merge", "per-polygon", "detach", "server"}) {
    if (args.has(job_flag)) {
      return Fail(absl::InvalidArgumentError(absl::StrCat(
          "--meshlets builds meshlets in this process and runs no clustering job: drop --",
          job_flag)));
    }
  }
  const std::string& input_path = args.positional()[0];
  MeshletOptions options;
  absl::StatusOr<uint64_t> max_vertices =
      args.GetUint("max-vertices", options.max_vertices, kMaxMeshletVertices);
  if (!max_vertices.ok()) return Fail(max_vertices.status());
  absl::StatusOr<uint64_t> max_triangles =
      args.GetUint("max-triangles", options.max_triangles, kMaxMeshletTriangles);
  if (!max_triangles.ok()) return Fail(max_triangles.status());
  options.max_vertices = static_cast<uint32_t>(*max_vertices);
  options.max_triangles = static_cast<uint32_t>(*max_triangles);
  if (args.has("cone-weight")) {
    double weight = 0;
    if (!absl::SimpleAtod(args.get("cone-weight"), &weight) || !(weight >= 0 && weight <= 1)) {
      return Fail(absl::InvalidArgumentError(absl::StrCat(
          "--cone-weight: '", args.get("cone-weight"), "' is not a number in [0, 1]")));
    }
    options.cone_weight = static_cast<float>(weight);
  }
  if (absl::Status status = ValidateMeshletOptions(options); !status.ok()) {
    return Fail(absl::InvalidArgumentError(absl::StrCat("--meshlets: ", status.message())));
  }
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(input_path);
  if (!mesh.ok()) return Fail(mesh.status());
  const absl::Time start = absl::Now();
  absl::StatusOr<MeshletResult> meshlets = BuildMeshlets(*mesh, options);
  const double seconds = absl::ToDoubleSeconds(absl::Now() - start);
  if (!meshlets.ok()) {
    return Fail(absl::Status(meshlets.status().code(),
                             absl::StrCat(input_path, ": ", meshlets.status().message())));
  }
  const std::string path = args.get("meshlets");
  const absl::Status written =
      absl::EndsWithIgnoreCase(path, ".glb")
          ? WriteMeshletGlb(path, *mesh, *meshlets, options.max_vertices, options.max_triangles)
          : WriteMeshletFile(path, *meshlets, static_cast<uint32_t>(mesh->num_vertices()),
                             options.max_vertices, options.max_triangles);
  if (!written.ok()) return Fail(written);
  if (args.has("labels")) {
    if (absl::Status s = WriteLabels(args.get("labels"), meshlets->face_meshlet); !s.ok()) {
      return Fail(s);
    }
  }
  const size_t count = meshlets->meshlets.size();
  const double fill = static_cast<double>(mesh->num_faces()) / static_cast<double>(count);
  const double vertices_per_triangle = static_cast<double>(meshlets->meshlet_vertices.size()) /
                                       static_cast<double>(mesh->num_faces());
  if (args.has("json")) {
    std::printf(
        "{\"input\": %s, \"faces\": %zu, \"meshlets\": %zu, \"max_vertices\": %u, "
        "\"max_triangles\": %u, \"cone_weight\": %s, \"fill\": %s, "
        "\"vertices_per_triangle\": %s, \"seconds\": %s, \"file\": %s}\n",
        JsonString(input_path).c_str(), mesh->num_faces(), count, options.max_vertices,
        options.max_triangles, JsonNumber(options.cone_weight).c_str(), JsonNumber(fill).c_str(),
        JsonNumber(vertices_per_triangle).c_str(), JsonNumber(seconds).c_str(),
        JsonString(path).c_str());
  } else {
    std::printf(
        "%s: %zu faces in %zu meshlets (at most %u vertices, %u triangles; %.1f triangles and "
        "%.3f vertices per triangle on average) in %.3f s: %s\n",
        input_path.c_str(), mesh->num_faces(), count, options.max_vertices, options.max_triangles,
        fill, vertices_per_triangle, seconds, path.c_str());
  }
  return 0;
}

}  // namespace mlclust::cli
