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
  EXPECT_THAT(FindElbows(counts, energy), ElementsAre(6u));
  // Our any-jump rule also reports the jump at 2, which no plateau precedes.
  ElbowOptions any_jump;
  any_jump.rule = ElbowOptions::Rule::kAnyJump;
  EXPECT_THAT(FindElbows(counts, energy, any_jump), ElementsAre(6u, 2u));
}

TEST(FindElbowsTest, ASteadyRiseFromZeroHasNoElbowByTheTextsDefinition) {
  // fandisk's ML curve with the planar energy from 64 clusters down to 1 (ml_bench
  // data/fandisk.off --energy planar --curve): zero while the clusters are flat (down to
  // 7,646 clusters), then a steady rise, at most 1.6x per level, and 2.5x for the last
  // merge. No zero plateau ends in a jump, so by the text's definition there is no elbow;
  // our any-jump rule reports the last merge, 2.
  const std::vector<double> energy = {
      0.003536, 0.003697, 0.003798, 0.003932, 0.004096, 0.004342, 0.004593, 0.004853,
      0.005035, 0.005256, 0.005597, 0.005955, 0.00623,  0.006457, 0.006715, 0.006939,
      0.007368, 0.007599, 0.007772, 0.008143, 0.008479, 0.00886,  0.009455, 0.01006,
      0.01071,  0.01125,  0.01181,  0.01245,  0.01305,  0.01374,  0.0147,   0.01557,
      0.01658,  0.0179,   0.01997,  0.02271,  0.02454,  0.02807,  0.03096,  0.03388,
      0.03943,  0.04286,  0.04715,  0.05268,  0.06416,  0.07311,  0.08712,  0.0993,
      0.1129,   0.1283,   0.1345,   0.1571,   0.2003,   0.2153,   0.2738,   0.299,
      0.3802,   0.4201,   0.5132,   0.6289,   0.7568,   1.216,    1.749,    4.412};
  std::vector<uint32_t> counts;
  for (uint32_t k = 64; k >= 1; --k) counts.push_back(k);
  ASSERT_EQ(counts.size(), energy.size());
  EXPECT_TRUE(FindElbows(counts, energy).empty());
  ElbowOptions any_jump;
  any_jump.rule = ElbowOptions::Rule::kAnyJump;
  EXPECT_THAT(FindElbows(counts, energy, any_jump), ElementsAre(2u));
}

TEST(FindElbowsTest, ElbowsComeInLevelOrderNotByStrength) {
  // A weak jump at 7 (x3) before a strong one at 3 (x20): the first met comes first.
  const std::vector<uint32_t> counts = {8, 7, 6, 5, 4, 3, 2, 1};
  const std::vector<double> energy = {90, 100, 300, 310, 320, 330, 6600, 6800};
  ElbowOptions any_jump;
  any_jump.rule = ElbowOptions::Rule::kAnyJump;
  EXPECT_THAT(FindElbows(counts, energy, any_jump), ElementsAre(7u, 3u));
  // By the text's rule only 7 ends a plateau (100 is under 2 % of 6,800; 330 is not).
  EXPECT_THAT(FindElbows(counts, energy), ElementsAre(7u));
  ElbowOptions one = any_jump;
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
