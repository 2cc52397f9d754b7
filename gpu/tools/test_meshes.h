// Meshes generated in code for the gpu tests and mlclust-gpu-info (header-only; not part
// of the library's API). Large real meshes are read through core's mesh I/O elsewhere;
// these give parity checks and timings a known size with no files.
#ifndef MLCLUST_GPU_TOOLS_TEST_MESHES_H_
#define MLCLUST_GPU_TOOLS_TEST_MESHES_H_

#include <cmath>
#include <cstdint>
#include <map>
#include <random>
#include <utility>
#include <vector>

#include "core/base/ids.h"
#include "core/mesh/mesh.h"

namespace mlclust::gpu::testing {

// A rows x cols grid of unit squares in the xy plane, each split into two
// counter-clockwise triangles (2 * rows * cols faces), with every vertex moved by up to
// `jitter` in x, y and z so areas and normals vary. Deterministic for a given seed.
inline TriangleMesh MakeJitteredGrid(uint32_t rows, uint32_t cols, float jitter,
                                     uint32_t seed = 1) {
  TriangleMesh mesh;
  std::mt19937 random(seed);
  std::uniform_real_distribution<float> offset(-jitter, jitter);
  mesh.positions.reserve(3 * size_t{rows + 1} * (cols + 1));
  for (uint32_t r = 0; r <= rows; ++r) {
    for (uint32_t c = 0; c <= cols; ++c) {
      mesh.positions.push_back(static_cast<float>(c) + offset(random));
      mesh.positions.push_back(static_cast<float>(r) + offset(random));
      mesh.positions.push_back(offset(random));
    }
  }
  mesh.indices.reserve(6 * size_t{rows} * cols);
  const auto vertex = [cols](uint32_t r, uint32_t c) { return r * (cols + 1) + c; };
  for (uint32_t r = 0; r < rows; ++r) {
    for (uint32_t c = 0; c < cols; ++c) {
      const uint32_t v00 = vertex(r, c), v01 = vertex(r, c + 1);
      const uint32_t v10 = vertex(r + 1, c), v11 = vertex(r + 1, c + 1);
      mesh.indices.insert(mesh.indices.end(), {v00, v01, v11, v00, v11, v10});
    }
  }
  return mesh;
}

// Labels of MakeJitteredGrid faces in square blocks of block x block cells: the shape of
// a clustering midway through ML, with long cluster boundaries.
inline std::vector<ClusterId> GridBlockLabels(uint32_t rows, uint32_t cols, uint32_t block) {
  std::vector<ClusterId> labels;
  labels.reserve(2 * size_t{rows} * cols);
  const uint32_t blocks_per_row = (cols + block - 1) / block;
  for (uint32_t r = 0; r < rows; ++r) {
    for (uint32_t c = 0; c < cols; ++c) {
      const ClusterId label((r / block) * blocks_per_row + c / block);
      labels.push_back(label);
      labels.push_back(label);
    }
  }
  return labels;
}

// The unit icosahedron subdivided `subdivisions` times (20 * 4^subdivisions faces), every
// vertex projected onto the sphere of `radius` about `center`.
inline TriangleMesh MakeIcosphere(int subdivisions, double radius = 1.0, double center_x = 0.0,
                                  double center_y = 0.0, double center_z = 0.0) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<double> points = {-1, t,  0,  1, t, 0,  -1, -t, 0,  1, -t, 0, 0,  -1, t,  0,  1, t,
                                0,  -1, -t, 0, 1, -t, t,  0,  -1, t, 0,  1, -t, 0,  -1, -t, 0, 1};
  std::vector<uint32_t> faces = {0, 11, 5,  0, 5,  1, 0, 1, 7, 0, 7,  10, 0, 10, 11, 1, 5, 9, 5, 11,
                                 4, 11, 10, 2, 10, 7, 6, 7, 1, 8, 3,  9,  4, 3,  4,  2, 3, 2, 6, 3,
                                 6, 8,  3,  8, 9,  4, 9, 5, 2, 4, 11, 6,  2, 10, 8,  6, 7, 9, 8, 1};
  for (int level = 0; level < subdivisions; ++level) {
    std::map<std::pair<uint32_t, uint32_t>, uint32_t> midpoints;
    const auto midpoint = [&](uint32_t a, uint32_t b) {
      const auto key = std::minmax(a, b);
      auto [it, inserted] = midpoints.emplace(key, static_cast<uint32_t>(points.size() / 3));
      if (inserted) {
        for (int k = 0; k < 3; ++k) points.push_back(0.5 * (points[3 * a + k] + points[3 * b + k]));
      }
      return it->second;
    };
    std::vector<uint32_t> finer;
    finer.reserve(4 * faces.size());
    for (size_t f = 0; f < faces.size(); f += 3) {
      const uint32_t a = faces[f], b = faces[f + 1], c = faces[f + 2];
      const uint32_t ab = midpoint(a, b), bc = midpoint(b, c), ca = midpoint(c, a);
      finer.insert(finer.end(), {a, ab, ca, b, bc, ab, c, ca, bc, ab, bc, ca});
    }
    faces = std::move(finer);
  }
  TriangleMesh mesh;
  mesh.positions.reserve(points.size());
  const double center[3] = {center_x, center_y, center_z};
  for (size_t v = 0; v < points.size(); v += 3) {
    const double norm = std::sqrt(points[v] * points[v] + points[v + 1] * points[v + 1] +
                                  points[v + 2] * points[v + 2]);
    for (int k = 0; k < 3; ++k) {
      mesh.positions.push_back(static_cast<float>(center[k] + radius * points[v + k] / norm));
    }
  }
  mesh.indices = std::move(faces);
  return mesh;
}

}  // namespace mlclust::gpu::testing

#endif  // MLCLUST_GPU_TOOLS_TEST_MESHES_H_
