#include "client/clustered_mesh_file.h"

#include <cstdio>
#include <optional>

#include "absl/status/statusor.h"
#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "core/io/mesh_io.h"

namespace mlclust::client {

absl::StatusOr<ClusteredMeshFormat> ClusteredMeshFormatOf(const std::string& flag,
                                                          const std::string& path) {
  const size_t dot = path.find_last_of("./");
  const std::string extension = dot == std::string::npos || path[dot] != '.'
                                    ? std::string()
                                    : absl::AsciiStrToLower(path.substr(dot));
  if (extension == ".ply") return ClusteredMeshFormat::kPly;
  if (extension == ".glb" || extension == ".gltf") return ClusteredMeshFormat::kGltf;
  if (extension == ".obj") return ClusteredMeshFormat::kObj;
  return absl::InvalidArgumentError(
      absl::StrCat(flag.empty() ? "" : absl::StrCat(flag, " "), path, ": cannot write ",
                   extension.empty() ? std::string("a file without extension")
                                     : absl::StrCat("'", extension, "' files"),
                   " (the format follows the extension: .ply, .glb, .gltf or .obj)"));
}

absl::Status CheckClusteredMeshOutputs(const std::optional<std::string>& out,
                                       const std::optional<std::string>& ply) {
  if (out.has_value()) {
    absl::StatusOr<ClusteredMeshFormat> format = ClusteredMeshFormatOf("--out", *out);
    if (!format.ok()) return format.status();
  }
  if (!ply.has_value()) return absl::OkStatus();
  absl::StatusOr<ClusteredMeshFormat> format = ClusteredMeshFormatOf("--ply", *ply);
  if (format.ok() && *format == ClusteredMeshFormat::kPly) return absl::OkStatus();
  if (format.ok()) {
    const std::string extension = ply->substr(ply->find_last_of('.'));
    return absl::InvalidArgumentError(
        absl::StrCat("--ply ", *ply, ": --ply writes a PLY file, which the name ", extension,
                     " would misname; give --out ", *ply, " to write ",
                     *format == ClusteredMeshFormat::kGltf ? "glTF" : "OBJ",
                     " (its format follows the extension), or a .ply name"));
  }
  return absl::InvalidArgumentError(
      absl::StrCat("--ply ", *ply,
                   ": --ply writes PLY: give a .ply name, or --out FILE with .ply, .glb, "
                   ".gltf or .obj"));
}

absl::Status WriteClusteredMesh(const std::string& path, const TriangleMesh& mesh,
                                std::span<const ClusterId> labels) {
  absl::StatusOr<ClusteredMeshFormat> format = ClusteredMeshFormatOf("", path);
  if (!format.ok()) return format.status();
  switch (*format) {
    case ClusteredMeshFormat::kPly:
      return WriteClusteredPly(path, mesh, labels);
    case ClusteredMeshFormat::kGltf:
      return WriteClusteredGltf(path, mesh, labels);
    case ClusteredMeshFormat::kObj:
      return WriteClusteredObj(path, mesh, labels);
  }
  return absl::InternalError("unreachable");
}

absl::Status WriteClusteredObj(const std::string& path, const TriangleMesh& mesh,
                               std::span<const ClusterId> labels) {
  const size_t nv = mesh.num_vertices(), nf = mesh.num_faces();
  if (labels.size() != nf) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": ", labels.size(), " labels for ", nf,
                                                   " faces (one per face is needed)"));
  }
  for (size_t f = 0; f < nf; ++f) {
    for (int c = 0; c < 3; ++c) {
      if (mesh.indices[3 * f + c] >= nv) {
        return absl::InvalidArgumentError(absl::StrCat(path, ": face ", f, " names vertex ",
                                                       mesh.indices[3 * f + c], " of ", nv));
      }
    }
  }
  std::FILE* out = std::fopen(path.c_str(), "wb");
  if (out == nullptr) return absl::UnavailableError(absl::StrCat("cannot write ", path));
  std::fprintf(out, "# written by mlclust: %zu vertices, %zu faces, a group per cluster\n", nv, nf);
  for (size_t v = 0; v < nv; ++v) {
    std::fprintf(out, "v %.9g %.9g %.9g\n", mesh.positions[3 * v], mesh.positions[3 * v + 1],
                 mesh.positions[3 * v + 2]);
  }
  std::optional<ClusterId> group;
  for (size_t f = 0; f < nf; ++f) {
    if (!group.has_value() || *group != labels[f]) {
      group = labels[f];
      if (labels[f] == ClusterId::Invalid()) {
        std::fputs("g unclustered\n", out);
      } else {
        std::fprintf(out, "g cluster_%u\n", labels[f].value());
      }
    }
    std::fprintf(out, "f %u %u %u\n", mesh.indices[3 * f] + 1, mesh.indices[3 * f + 1] + 1,
                 mesh.indices[3 * f + 2] + 1);
  }
  if (std::fclose(out) != 0) return absl::UnavailableError(absl::StrCat("cannot write ", path));
  return absl::OkStatus();
}

}  // namespace mlclust::client
