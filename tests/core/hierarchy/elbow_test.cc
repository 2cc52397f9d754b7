#include "core/hierarchy/elbow.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <vector>

#include "core/cluster/multilevel.h"
#include "core/hierarchy/hierarchy.h"
#include "tests/fixtures/test_meshes.h"

namespace mlclust {
namespace {

using ::testing::ElementsAre;

TEST(FindElbowsTest, TheEndOfAZeroPlateauIsAnElbow) {
  // Exactly zero down to 6 clusters, then a fast rise: the text's picture (Fig. 4.22).
  const std::vector<uint32_t> counts = {9, 8, 7, 6, 5, 4, 3, 2, 1};
  const std::vector<double> energy = {0, 0, 0, 0, 1.2, 2.3, 3.5, 5.1, 12};
  EXPECT_THAT(FindElbows(counts, energy), ElementsAre(6u, 2u));
}

TEST(FindElbowsTest, ElbowsComeInLevelOrderNotByStrength) {
  // A weak jump at 7 (x3) before a strong one at 3 (x20): the first met comes first.
  const std::vector<uint32_t> counts = {8, 7, 6, 5, 4, 3, 2, 1};
  const std::vector<double> energy = {90, 100, 300, 310, 320, 330, 6600, 6800};
  EXPECT_THAT(FindElbows(counts, energy), ElementsAre(7u, 3u));
  ElbowOptions one;
  one.max_elbows = 1;
  EXPECT_THAT(FindElbows(counts, energy, one), ElementsAre(7u));
}

TEST(FindElbowsTest, RoundingNoiseIsNoElbowAndAFlatCurveHasNone) {
  const std::vector<uint32_t> counts = {8, 7, 6, 5, 4, 3, 2, 1};
  // 2e-9 -> 1e-3 is a big ratio, but both are at most 0.1% of the largest: no elbow at 6.
  const std::vector<double> energy = {0, 1e-9, 2e-9, 0.001, 0.5, 0.7, 0.9, 1.0};
  EXPECT_THAT(FindElbows(counts, energy), ElementsAre(5u));
  EXPECT_TRUE(FindElbows(counts, std::vector<double>(8, 0.0)).empty());
  EXPECT_TRUE(FindElbows(counts, std::vector<double>(8, 1.0)).empty());
  // A steady rise by less than `jump` per level has no elbow either.
  std::vector<double> steady;
  for (int l = 0; l < 8; ++l) steady.push_back(std::pow(1.5, l));
  EXPECT_TRUE(FindElbows(counts, steady).empty());
  EXPECT_TRUE(FindElbows({}, {}).empty());
}

// ---------------------------------------------------------------------------------------
// The real engine on solids whose true shapes are known.

// A solid of revolution about the z axis made of three smooth shapes: a cap of sphere 1
// (centre z = -0.6, through the circle r = 1 at z = 0), a zone of sphere 2 (centre z = 0.2,
// through the same circle) from z = 0 down to z = -0.5, and the flat disc closing it there.
// `segments` vertices per ring; `patch` holds the true shape of each face.
testing::SphericalPatchModel TwoSpheresAndAPlane(int segments) {
  testing::SphericalPatchModel model;
  TriangleMesh& mesh = model.mesh;
  const double pi = 3.14159265358979323846;
  const double c1 = -0.6, r1 = std::sqrt(1 + c1 * c1);
  const double c2 = 0.2, r2 = std::sqrt(1 + c2 * c2);
  const double bottom = -0.5, disc = std::sqrt(r2 * r2 - (bottom - c2) * (bottom - c2));
  auto add_point = [&](double r, double z, double t) {
    mesh.positions.insert(mesh.positions.end(),
                          {static_cast<float>(r * std::cos(t)), static_cast<float>(r * std::sin(t)),
                           static_cast<float>(z)});
  };
  auto add_ring = [&](double r, double z) {
    const uint32_t first = static_cast<uint32_t>(mesh.num_vertices());
    for (int j = 0; j < segments; ++j) add_point(r, z, 2 * pi * j / segments);
    return first;
  };
  // Rings from the top down; `upper` above `lower`.
  auto band = [&](uint32_t upper, uint32_t lower, uint32_t shape) {
    for (int j = 0; j < segments; ++j) {
      const uint32_t a = lower + j, b = lower + (j + 1) % segments;
      const uint32_t c = upper + j, d = upper + (j + 1) % segments;
      mesh.indices.insert(mesh.indices.end(), {a, b, d, a, d, c});
      model.patch.insert(model.patch.end(), 2, ClusterId(shape));
    }
  };
  auto fan = [&](uint32_t pole, uint32_t ring, uint32_t shape, bool top) {
    for (int j = 0; j < segments; ++j) {
      const uint32_t a = ring + j, b = ring + (j + 1) % segments;
      if (top) {
        mesh.indices.insert(mesh.indices.end(), {pole, a, b});
      } else {
        mesh.indices.insert(mesh.indices.end(), {pole, b, a});
      }
      model.patch.push_back(ClusterId(shape));
    }
  };
  // Cap of sphere 1: polar angle from the pole down to the circle at z = 0.
  const uint32_t top_pole = static_cast<uint32_t>(mesh.num_vertices());
  add_point(0, c1 + r1, 0);
  const double cap_angle = std::acos(-c1 / r1);  // the angle of the circle r = 1, z = 0
  uint32_t previous = 0;
  const int cap_rings = 6;
  for (int i = 1; i <= cap_rings; ++i) {
    const double angle = cap_angle * i / cap_rings;
    const double r = i == cap_rings ? 1.0 : r1 * std::sin(angle);
    const double z = i == cap_rings ? 0.0 : c1 + r1 * std::cos(angle);
    const uint32_t ring = add_ring(r, z);
    if (i == 1) {
      fan(top_pole, ring, 0, true);
    } else {
      band(previous, ring, 0);
    }
    previous = ring;
  }
  // Zone of sphere 2, from z = 0 down to z = bottom.
  const int zone_rings = 4;
  for (int i = 1; i <= zone_rings; ++i) {
    const double z = bottom * i / zone_rings;
    const double r = i == zone_rings ? disc : std::sqrt(r2 * r2 - (z - c2) * (z - c2));
    const uint32_t ring = add_ring(r, z);
    band(previous, ring, 1);
    previous = ring;
  }
  // The disc at z = bottom.
  const int disc_rings = 3;
  for (int i = 1; i < disc_rings; ++i) {
    const uint32_t ring = add_ring(disc * (disc_rings - i) / disc_rings, bottom);
    band(previous, ring, 2);
    previous = ring;
  }
  const uint32_t bottom_pole = static_cast<uint32_t>(mesh.num_vertices());
  add_point(0, bottom, 0);
  fan(bottom_pole, previous, 2, false);
  return model;
}

struct Curve {
  std::vector<uint32_t> counts;
  std::vector<double> energies;
};

Curve MultilevelCurve(const testing::LoadedMesh& loaded, MeshEnergyKind kind) {
  HierarchyLog log;
  const absl::StatusOr<MultilevelSummary> summary =
      RunMultilevel(loaded.problem(kind), MultilevelOptions{}, log);
  EXPECT_TRUE(summary.ok()) << summary.status();
  Curve curve;
  for (size_t level = 0; level < log.num_levels(); ++level) {
    curve.counts.push_back(log.cluster_count(level));
    curve.energies.push_back(log.energy(level));
  }
  return curve;
}

std::string Tail(const Curve& curve, size_t n) {
  std::string text;
  for (size_t l = curve.counts.size() > n ? curve.counts.size() - n : 0; l < curve.counts.size();
       ++l) {
    text += std::to_string(curve.counts[l]) + ":" + std::to_string(curve.energies[l]) + " ";
  }
  return text;
}

// Section 4.4 with the planar energy: the six sides of a cube merge at no cost, the
// seventh-to-last merge is the first that costs, so the first elbow is 6.
TEST(ElbowOfTheEngineTest, CubeWithThePlanarEnergyHasItsElbowAtSix) {
  const testing::LoadedMesh cube = testing::Load(testing::MakeCube(4).mesh);
  ASSERT_EQ(cube.mesh.num_faces(), 192u);
  const Curve curve = MultilevelCurve(cube, MeshEnergyKind::kPlanar);
  const std::vector<uint32_t> elbows = FindElbows(curve.counts, curve.energies);
  ASSERT_FALSE(elbows.empty()) << Tail(curve, 10);
  EXPECT_EQ(elbows.front(), 6u) << Tail(curve, 10);
  std::printf("planar energy, last levels: %s\n", Tail(curve, 8).c_str());
}

// Section 4.4 with the sphere energy (Figs. 4.21/4.22: planes first, then the spheres): two
// spherical patches and a plane; the first elbow is 3.
TEST(ElbowOfTheEngineTest, TwoSpheresAndAPlaneWithTheSphereEnergyHaveTheirElbowAtThree) {
  const testing::SphericalPatchModel model = TwoSpheresAndAPlane(24);
  const testing::LoadedMesh solid = testing::Load(model.mesh);
  ASSERT_EQ(model.patch.size(), solid.mesh.num_faces());
  const Curve curve = MultilevelCurve(solid, MeshEnergyKind::kSphere);
  const std::vector<uint32_t> elbows = FindElbows(curve.counts, curve.energies);
  ASSERT_FALSE(elbows.empty()) << Tail(curve, 10);
  EXPECT_EQ(elbows.front(), 3u) << Tail(curve, 10);
  std::printf("sphere energy, last levels: %s\n", Tail(curve, 6).c_str());
  // The level with three clusters is the true one, up to rounding.
  MeshEnergyOptions sphere;
  sphere.kind = MeshEnergyKind::kSphere;
  const double truth = MeshEnergyOfLabels(sphere, solid.mesh, model.patch);
  const auto three = std::find(curve.counts.begin(), curve.counts.end(), 3u);
  ASSERT_NE(three, curve.counts.end());
  EXPECT_LE(curve.energies[three - curve.counts.begin()], truth * (1 + 1e-9) + 1e-12);
}

}  // namespace
}  // namespace mlclust
