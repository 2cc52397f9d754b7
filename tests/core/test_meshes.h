// Tiny meshes built in code for tests.
#ifndef MLCLUST_TESTS_CORE_TEST_MESHES_H_
#define MLCLUST_TESTS_CORE_TEST_MESHES_H_

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

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

// A height field made of `columns` x `rows` spherical patches: over the rectangle
// [0, columns] x [0, rows], z is the upper envelope of one sphere per unit cell, each with
// its own radius (so neighbouring patches differ in curvature). The envelope is continuous
// and each patch lies on its sphere; only triangles crossing a patch border are not on a
// single sphere. `resolution` grid squares per unit; two triangles per square. `patch`
// holds, per face, the sphere that is highest at the face's centroid: the true clustering.
struct SphericalPatchModel {
  TriangleMesh mesh;
  std::vector<ClusterId> patch;
};

inline SphericalPatchModel SphericalPatches(int columns, int rows, int resolution) {
  struct Sphere {
    double cx, cy, cz, radius;
  };
  std::vector<Sphere> spheres;
  for (int j = 0; j < rows; ++j) {
    for (int i = 0; i < columns; ++i) {
      const int index = j * columns + i;
      const double radius = 0.8 + 0.5 * ((index * 7) % 5);  // 0.8 .. 2.8
      // Centre below the cell so that the cap's top is at height 1 + 0.1 * (index % 3).
      const double top = 1.0 + 0.1 * (index % 3);
      spheres.push_back({i + 0.5, j + 0.5, top - radius, radius});
    }
  }
  auto highest = [&](double x, double y, double* z) {
    int best = -1;
    *z = -1e30;
    for (size_t s = 0; s < spheres.size(); ++s) {
      const Sphere& sphere = spheres[s];
      const double r2 = sphere.radius * sphere.radius - (x - sphere.cx) * (x - sphere.cx) -
                        (y - sphere.cy) * (y - sphere.cy);
      if (r2 > 0 && sphere.cz + std::sqrt(r2) > *z) {
        *z = sphere.cz + std::sqrt(r2);
        best = static_cast<int>(s);
      }
    }
    return best;
  };
  SphericalPatchModel model;
  TriangleMesh& mesh = model.mesh;
  const int nx = columns * resolution, ny = rows * resolution;
  for (int y = 0; y <= ny; ++y) {
    for (int x = 0; x <= nx; ++x) {
      const double px = static_cast<double>(x) / resolution;
      const double py = static_cast<double>(y) / resolution;
      double z;
      highest(px, py, &z);
      mesh.positions.insert(mesh.positions.end(), {static_cast<float>(px), static_cast<float>(py),
                                                   static_cast<float>(z)});
    }
  }
  for (int y = 0; y < ny; ++y) {
    for (int x = 0; x < nx; ++x) {
      const uint32_t a = y * (nx + 1) + x, b = a + 1, c = a + nx + 1, d = c + 1;
      mesh.indices.insert(mesh.indices.end(), {a, b, c, c, b, d});
    }
  }
  for (size_t f = 0; f < mesh.num_faces(); ++f) {
    double x = 0, y = 0, z;
    for (int c = 0; c < 3; ++c) {
      x += mesh.positions[3 * mesh.indices[3 * f + c]] / 3.0;
      y += mesh.positions[3 * mesh.indices[3 * f + c] + 1] / 3.0;
    }
    model.patch.push_back(ClusterId(static_cast<uint32_t>(highest(x, y, &z))));
  }
  return model;
}

inline std::string DataPath(const std::string& name) {
  return std::string(MLCLUST_DATA_DIR) + "/" + name;
}

}  // namespace mlclust::testing

#endif  // MLCLUST_TESTS_CORE_TEST_MESHES_H_
