// A clustering as the binary PLY bench/render_ply.py reads: float x y z + uchar r g b per
// vertex (grey), uchar count + int indices + uchar r g b per face (its cluster's colour,
// core/io's ClusterColour). For the experiments' pictures only.
#ifndef MLCLUST_BENCH_EXPERIMENTS_CLUSTERED_PLY_H_
#define MLCLUST_BENCH_EXPERIMENTS_CLUSTERED_PLY_H_

#include <array>
#include <cstdint>
#include <cstdio>
#include <span>
#include <string>

#include "core/base/ids.h"
#include "core/io/mesh_io.h"
#include "core/mesh/mesh.h"

namespace mlclust::bench {

// False if the file cannot be written.
inline bool WriteClusteredPly(const std::string& path, const TriangleMesh& mesh,
                              std::span<const ClusterId> labels) {
  std::FILE* out = std::fopen(path.c_str(), "wb");
  if (out == nullptr) return false;
  std::fprintf(out,
               "ply\nformat binary_little_endian 1.0\nelement vertex %zu\nproperty float x\n"
               "property float y\nproperty float z\nproperty uchar red\nproperty uchar green\n"
               "property uchar blue\nelement face %zu\nproperty list uchar int "
               "vertex_indices\nproperty uchar red\nproperty uchar green\nproperty uchar "
               "blue\nend_header\n",
               mesh.num_vertices(), mesh.num_faces());
  const uint8_t grey[3] = {200, 200, 200};
  for (size_t v = 0; v < mesh.num_vertices(); ++v) {
    std::fwrite(&mesh.positions[3 * v], sizeof(float), 3, out);
    std::fwrite(grey, 1, 3, out);
  }
  for (size_t f = 0; f < mesh.num_faces(); ++f) {
    const uint8_t three = 3;
    std::fwrite(&three, 1, 1, out);
    for (int c = 0; c < 3; ++c) {
      const int32_t index = static_cast<int32_t>(mesh.indices[3 * f + c]);
      std::fwrite(&index, sizeof(index), 1, out);
    }
    const std::array<uint8_t, 3> colour = ClusterColour(labels[f].value());
    std::fwrite(colour.data(), 1, 3, out);
  }
  return std::fclose(out) == 0;
}

}  // namespace mlclust::bench

#endif  // MLCLUST_BENCH_EXPERIMENTS_CLUSTERED_PLY_H_
