// Tiny meshes built in code for tests.
#ifndef MLCLUST_TESTS_CORE_TEST_MESHES_H_
#define MLCLUST_TESTS_CORE_TEST_MESHES_H_

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "core/face_measures.h"
#include "core/mesh.h"
#include "core/mesh_clustering.h"
#include "core/mesh_io.h"

namespace mlclust::testing {

inline constexpr uint32_t kInvalidRing = 0xffffffffu;

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

// A closed "string of beads" made of `patches` spherical zones along the z axis: zone i
// lies on its own sphere (centre on the axis), neighbouring zones meet along a shared
// circle, and the two end zones run on to their sphere's pole. Every triangle has its three
// corners on its zone's sphere, so the true clustering (`patch`, per face) has a sphere
// energy of nearly zero (only chords versus arcs), while merging two zones does not.
// `rings` rings of vertices per zone, `segments` vertices per ring.
inline SphericalPatchModel SphericalBeads(int patches, int rings, int segments) {
  // Boundary circles at z = 0, 1, 2, ... with radii that vary from circle to circle.
  const double radius_pattern[] = {1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0};
  auto circle = [&](int b) { return radius_pattern[b % 12]; };
  struct Sphere {
    double centre_z, radius;
  };
  std::vector<Sphere> spheres;
  for (int i = 0; i < patches; ++i) {
    // The sphere through circles (z = i, r = rho_a) and (z = i + 1, r = rho_b):
    // rho_a^2 + (i - c)^2 = rho_b^2 + (i + 1 - c)^2.
    const double a = circle(i), b = circle(i + 1);
    const double c = (b * b - a * a + 2.0 * i + 1.0) / 2.0;
    spheres.push_back({c, std::sqrt(a * a + (i - c) * (i - c))});
  }
  SphericalPatchModel model;
  TriangleMesh& mesh = model.mesh;
  const double pi = 3.14159265358979323846;
  auto add_ring = [&](double z, double r) {
    const uint32_t first = static_cast<uint32_t>(mesh.num_vertices());
    for (int j = 0; j < segments; ++j) {
      const double t = 2 * pi * j / segments;
      mesh.positions.insert(mesh.positions.end(),
                            {static_cast<float>(r * std::cos(t)),
                             static_cast<float>(r * std::sin(t)), static_cast<float>(z)});
    }
    return first;
  };
  auto add_point = [&](double z) {
    mesh.positions.insert(mesh.positions.end(), {0.0f, 0.0f, static_cast<float>(z)});
    return static_cast<uint32_t>(mesh.num_vertices() - 1);
  };
  auto profile = [&](const Sphere& s, double z) {
    return std::sqrt(std::max(0.0, s.radius * s.radius - (z - s.centre_z) * (z - s.centre_z)));
  };
  auto band = [&](uint32_t lower, uint32_t upper, int zone) {
    for (int j = 0; j < segments; ++j) {
      const uint32_t a = lower + j, b = lower + (j + 1) % segments;
      const uint32_t c = upper + j, d = upper + (j + 1) % segments;
      mesh.indices.insert(mesh.indices.end(), {a, b, d, a, d, c});
      model.patch.insert(model.patch.end(), 2, ClusterId(static_cast<uint32_t>(zone)));
    }
  };
  auto fan = [&](uint32_t pole, uint32_t ring, int zone, bool bottom) {
    for (int j = 0; j < segments; ++j) {
      const uint32_t a = ring + j, b = ring + (j + 1) % segments;
      if (bottom) {
        mesh.indices.insert(mesh.indices.end(), {pole, b, a});
      } else {
        mesh.indices.insert(mesh.indices.end(), {pole, a, b});
      }
      model.patch.push_back(ClusterId(static_cast<uint32_t>(zone)));
    }
  };
  // The bottom cap: sphere 0 from its pole up to the circle at z = 0.
  const Sphere& first_sphere = spheres.front();
  const double bottom_pole = first_sphere.centre_z - first_sphere.radius;
  const uint32_t bottom = add_point(bottom_pole);
  uint32_t previous = kInvalidRing;
  for (int r = 1; r <= rings; ++r) {
    const double z = bottom_pole + (0.0 - bottom_pole) * r / rings;
    const uint32_t ring = add_ring(z, r == rings ? circle(0) : profile(first_sphere, z));
    if (previous == kInvalidRing) {
      fan(bottom, ring, 0, true);
    } else {
      band(previous, ring, 0);
    }
    previous = ring;
  }
  // The zones: rings from circle i to circle i + 1 on sphere i.
  for (int i = 0; i < patches; ++i) {
    for (int r = 1; r <= rings; ++r) {
      const double z = i + static_cast<double>(r) / rings;
      const uint32_t ring = add_ring(z, r == rings ? circle(i + 1) : profile(spheres[i], z));
      band(previous, ring, i);
      previous = ring;
    }
  }
  // The top cap: the last sphere from the last circle up to its pole.
  const Sphere& last_sphere = spheres.back();
  const double top_pole = last_sphere.centre_z + last_sphere.radius;
  for (int r = 1; r < rings; ++r) {
    const double z = patches + (top_pole - patches) * r / rings;
    const uint32_t ring = add_ring(z, profile(last_sphere, z));
    band(previous, ring, patches - 1);
    previous = ring;
  }
  fan(add_point(top_pole), previous, patches - 1, false);
  return model;
}

inline std::string DataPath(const std::string& name) {
  return std::string(MLCLUST_DATA_DIR) + "/" + name;
}

// A validated mesh with its adjacency and face measures, ready for the drivers.
struct LoadedMesh {
  TriangleMesh mesh;
  FaceAdjacency adjacency;
  FaceMeasures measures;
  MeshProblem problem(MeshEnergyKind kind = MeshEnergyKind::kCvd) const {
    MeshProblem p{&mesh, &adjacency, &measures, {}};
    p.energy.kind = kind;
    return p;
  }
};

inline LoadedMesh Load(TriangleMesh mesh) {
  LoadedMesh l;
  l.mesh = std::move(mesh);
  EXPECT_TRUE(ValidateMesh(l.mesh).ok());
  l.adjacency = *BuildFaceAdjacency(l.mesh);
  l.measures = ComputeFaceMeasures(l.mesh);
  return l;
}

// A mesh of data/, loaded once per test binary.
inline const LoadedMesh& LoadDataFile(const std::string& name) {
  static auto* cache = new std::map<std::string, LoadedMesh>;
  auto it = cache->find(name);
  if (it == cache->end()) {
    absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(DataPath(name));
    EXPECT_TRUE(mesh.ok()) << mesh.status();
    it = cache->emplace(name, Load(mesh.ok() ? *std::move(mesh) : TriangleMesh{})).first;
  }
  return it->second;
}

}  // namespace mlclust::testing

#endif  // MLCLUST_TESTS_CORE_TEST_MESHES_H_
