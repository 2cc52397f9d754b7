// Tiny meshes built in code for tests.
#ifndef MLCLUST_TESTS_CORE_TEST_MESHES_H_
#define MLCLUST_TESTS_CORE_TEST_MESHES_H_

#include <string>

#include "core/mesh.h"

namespace mlclust::testing {

inline TriangleMesh MakeMesh(std::vector<float> positions, std::vector<uint32_t> indices) {
  TriangleMesh mesh;
  mesh.positions = std::move(positions);
  mesh.indices = std::move(indices);
  return mesh;
}

// A closed tetrahedron, outward counter-clockwise faces.
inline TriangleMesh Tetrahedron() {
  return MakeMesh({0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1}, {0, 2, 1, 0, 1, 3, 1, 2, 3, 0, 3, 2});
}

// Two triangles sharing the edge (1, 2): a unit square.
inline TriangleMesh TwoTriangles() {
  return MakeMesh({0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0}, {0, 1, 2, 2, 1, 3});
}

// Two triangles touching only at vertex 0: a non-manifold vertex.
inline TriangleMesh BowTie() {
  return MakeMesh({0, 0, 0, 1, 0, 0, 1, 1, 0, -1, 0, 0, -1, -1, 0}, {0, 1, 2, 0, 3, 4});
}

// An n x n grid of unit squares, two triangles each, in the z = 0 plane, optionally with
// the squares listed in `holes` (row-major square index) left out.
inline TriangleMesh Grid(int n, const std::vector<int>& holes = {}) {
  TriangleMesh mesh;
  for (int y = 0; y <= n; ++y) {
    for (int x = 0; x <= n; ++x) {
      mesh.positions.insert(mesh.positions.end(),
                            {static_cast<float>(x), static_cast<float>(y), 0.0f});
    }
  }
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      if (std::find(holes.begin(), holes.end(), y * n + x) != holes.end()) continue;
      const uint32_t a = y * (n + 1) + x, b = a + 1, c = a + n + 1, d = c + 1;
      mesh.indices.insert(mesh.indices.end(), {a, b, c, c, b, d});
    }
  }
  return mesh;
}

inline std::string DataPath(const std::string& name) {
  return std::string(MLCLUST_DATA_DIR) + "/" + name;
}

}  // namespace mlclust::testing

#endif  // MLCLUST_TESTS_CORE_TEST_MESHES_H_
