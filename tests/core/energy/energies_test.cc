#include "core/energy/energies.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>
#include <map>
#include <numeric>
#include <random>

#include "core/cluster/multilevel.h"
#include "core/hierarchy/hierarchy.h"
#include "core/io/mesh_io.h"
#include "core/mesh/face_measures.h"
#include "tests/fixtures/test_meshes.h"

namespace mlclust {
namespace {

TEST(FaceMeasuresTest, UnitSquareTriangles) {
  const FaceMeasures m = ComputeFaceMeasures(testing::TwoTriangles());
  ASSERT_EQ(m.num_faces(), 2u);
  EXPECT_DOUBLE_EQ(m.area[0], 0.5);
  EXPECT_DOUBLE_EQ(m.area[1], 0.5);
  EXPECT_DOUBLE_EQ(m.centroid[0].x, 1.0 / 3);
  EXPECT_DOUBLE_EQ(m.centroid[1].y, 2.0 / 3);
  EXPECT_DOUBLE_EQ(m.unit_normal[0].z, 1.0);
  EXPECT_DOUBLE_EQ(m.unit_normal[1].z, 1.0);
}

// Sums per cluster from the labels, then energy from sums (eq. 3.7).
double EnergyFromSums(const FaceMeasures& m, const std::vector<ClusterId>& labels, Vec3 origin) {
  std::map<uint32_t, CvdSums> sums;
  for (size_t j = 0; j < labels.size(); ++j) {
    sums[labels[j].value()] += CvdFaceSums(m.area[j], m.centroid[j], origin);
  }
  double energy = 0;
  for (const auto& [id, s] : sums) energy += CvdSumsEnergy(s);
  return energy;
}

std::vector<ClusterId> RandomLabels(size_t n, uint32_t k, uint32_t seed) {
  std::mt19937 rng(seed);
  std::vector<ClusterId> labels(n);
  for (auto& l : labels) l = ClusterId(rng() % k);
  return labels;
}

TEST(CvdEnergyTest, IncrementalEqualsDirectSumOnARealMesh) {
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(testing::DataPath("fandisk.off"));
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  const FaceMeasures m = ComputeFaceMeasures(*mesh);
  for (uint32_t k : {1u, 7u, 100u, 5000u}) {
    const std::vector<ClusterId> labels = RandomLabels(m.num_faces(), k, k);
    const double direct = CvdEnergyDirect(m, labels);
    ASSERT_GT(direct, 0);
    // With the origin near the mesh and far from it: the centred form must stay exact.
    EXPECT_NEAR(EnergyFromSums(m, labels, m.centroid[0]), direct, 1e-10 * direct) << k;
    EXPECT_NEAR(EnergyFromSums(m, labels, Vec3{}), direct, 1e-8 * direct) << k;
  }
}

TEST(CvdEnergyTest, MergeCostEqualsEnergyDifference) {
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(testing::DataPath("elephant.off"));
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  const FaceMeasures m = ComputeFaceMeasures(*mesh);
  std::mt19937 rng(3);
  for (int trial = 0; trial < 50; ++trial) {
    CvdSums a, b;
    for (size_t j = 0; j < m.num_faces(); ++j) {
      const uint32_t r = rng() % 10;
      if (r == 0) a += CvdFaceSums(m.area[j], m.centroid[j], m.centroid[0]);
      if (r == 1) b += CvdFaceSums(m.area[j], m.centroid[j], m.centroid[0]);
    }
    const double difference = CvdSumsEnergy(a + b) - CvdSumsEnergy(a) - CvdSumsEnergy(b);
    EXPECT_NEAR(CvdMergeCost(a, b), difference, 1e-9 * CvdSumsEnergy(a + b));
    EXPECT_GE(CvdMergeCost(a, b), 0);
  }
}

TEST(CvdEnergyTest, SingleFaceAndZeroAreaClustersHaveNoEnergy) {
  const CvdSums face = CvdFaceSums(2.0, {1, 2, 3}, {0, 0, 0});
  EXPECT_NEAR(CvdSumsEnergy(face), 0, 1e-12);
  const CvdSums empty = CvdFaceSums(0.0, {5, 5, 5}, {0, 0, 0});
  EXPECT_EQ(CvdSumsEnergy(empty), 0);
  EXPECT_EQ(CvdMergeCost(face, empty), 0);
  // Two unit-area faces two apart: cost = (1 * 1 / 2) * 4 = 2.
  EXPECT_DOUBLE_EQ(CvdMergeCost(CvdFaceSums(1, {0, 0, 0}, {}), CvdFaceSums(1, {2, 0, 0}, {})), 2.0);
}

}  // namespace
}  // namespace mlclust

namespace mlclust {
namespace {

struct RealMesh {
  TriangleMesh mesh;
  FaceMeasures measures;
};

const RealMesh& Elephant() {
  static const RealMesh* mesh = [] {
    auto* m = new RealMesh;
    m->mesh = *ReadMeshFile(testing::DataPath("elephant.off"));
    m->measures = ComputeFaceMeasures(m->mesh);
    return m;
  }();
  return *mesh;
}

class EveryEnergyTest : public ::testing::TestWithParam<MeshEnergyKind> {};

// Incremental form (energy from sums) equals the definition (each face against its
// cluster's best proxy), and merge costs equal energy differences, for every energy.
TEST_P(EveryEnergyTest, IncrementalEqualsDirectSumAndMergeCostIsTheDifference) {
  const RealMesh& real = Elephant();
  MeshEnergyOptions options;
  options.kind = GetParam();
  WithMeshEnergy(options, real.mesh, real.measures, [&](const auto& energy) {
    for (uint32_t k : {1u, 13u, 300u}) {
      const std::vector<ClusterId> labels = RandomLabels(real.measures.num_faces(), k, k + 1);
      const double from_sums = EnergyFromSums(energy, labels);
      const double direct = EnergyFromProxies(energy, labels);
      ASSERT_GT(direct, 0) << MeshEnergyName(options.kind) << " k=" << k;
      EXPECT_NEAR(from_sums, direct, 1e-9 * direct) << MeshEnergyName(options.kind) << " k=" << k;
    }
    // Merge cost of two random face sets, against the difference of energies.
    std::mt19937 rng(5);
    using Sums = typename std::decay_t<decltype(energy)>::Sums;
    for (int trial = 0; trial < 20; ++trial) {
      Sums a, b;
      for (uint32_t f = 0; f < real.measures.num_faces(); ++f) {
        const uint32_t r = rng() % 8;
        if (r == 0) a += energy.face_sums(f);
        if (r == 1) b += energy.face_sums(f);
      }
      const double cost = energy.MergeCost(a, b);
      const double difference = energy.Energy(a + b) - energy.Energy(a) - energy.Energy(b);
      EXPECT_NEAR(cost, difference, 1e-9 * energy.Energy(a + b));
      EXPECT_GE(cost, -1e-9 * energy.Energy(a + b));
      // Subtracting a part's sums gives the other part back (EMLO relies on it).
      Sums whole = a + b;
      whole -= b;
      EXPECT_NEAR(energy.Energy(whole), energy.Energy(a), 1e-9 * energy.Energy(a + b));
    }
  });
}

INSTANTIATE_TEST_SUITE_P(AllMeshEnergies, EveryEnergyTest,
                         ::testing::Values(MeshEnergyKind::kCvd, MeshEnergyKind::kCvdAdaptive,
                                           MeshEnergyKind::kMwcvdArea,
                                           MeshEnergyKind::kMwcvdVariance,
                                           MeshEnergyKind::kMwcvdMax, MeshEnergyKind::kPlanar,
                                           MeshEnergyKind::kSphere, MeshEnergyKind::kSphereNormals),
                         [](const auto& info) {
                           std::string name = MeshEnergyName(info.param);
                           std::replace(name.begin(), name.end(), '-', '_');
                           return name;
                         });

TEST(EnergiesTest, UniformCvdClassMatchesTheDefinition) {
  const RealMesh& real = Elephant();
  const std::vector<ClusterId> labels = RandomLabels(real.measures.num_faces(), 50, 9);
  const double direct = CvdEnergyDirect(real.measures, labels);
  EXPECT_NEAR(EnergyFromSums(CvdEnergy(real.measures), labels), direct, 1e-10 * direct);
}

// A triangulated sphere (an octahedron refined and pushed onto the unit sphere).
TriangleMesh UnitSphere(int refinements) {
  TriangleMesh mesh =
      testing::MakeMesh({1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1},
                        {0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4, 2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5});
  for (int r = 0; r < refinements; ++r) {
    std::map<std::pair<uint32_t, uint32_t>, uint32_t> midpoint;
    auto middle = [&](uint32_t a, uint32_t b) {
      auto key = std::minmax(a, b);
      auto it = midpoint.find(key);
      if (it != midpoint.end()) return it->second;
      Vec3 p = (mesh.position(VertexId(a)) + mesh.position(VertexId(b))) * 0.5;
      p = p / Norm(p);
      const uint32_t id = static_cast<uint32_t>(mesh.num_vertices());
      mesh.positions.insert(mesh.positions.end(), {float(p.x), float(p.y), float(p.z)});
      midpoint[key] = id;
      return id;
    };
    std::vector<uint32_t> refined;
    for (size_t f = 0; f < mesh.num_faces(); ++f) {
      const uint32_t a = mesh.indices[3 * f], b = mesh.indices[3 * f + 1],
                     c = mesh.indices[3 * f + 2];
      const uint32_t ab = middle(a, b), bc = middle(b, c), ca = middle(c, a);
      refined.insert(refined.end(), {a, ab, ca, ab, b, bc, ca, bc, c, ab, bc, ca});
    }
    mesh.indices = std::move(refined);
  }
  return mesh;
}

TEST(EnergiesTest, SphereEnergyIsNearZeroOnASphereAndFindsItsRadius) {
  const TriangleMesh sphere = UnitSphere(4);  // 2048 faces
  ASSERT_TRUE(ValidateMesh(sphere).ok());
  const FaceMeasures m = ComputeFaceMeasures(sphere);
  const SphereEnergy energy(m);
  const std::vector<ClusterId> one(m.num_faces(), ClusterId(0));
  // Chords put centroids slightly inside the sphere, by different amounts: a small, not
  // zero, misfit, against the centroids' spread of about 1 per face when R = 0.
  EXPECT_LT(EnergyFromSums(energy, one), 1e-3 * m.num_faces());
  SphereEnergy::Sums sums;
  for (uint32_t f = 0; f < m.num_faces(); ++f) sums += energy.face_sums(f);
  const SphereEnergy::Proxy proxy = energy.FitProxy(sums);
  EXPECT_FALSE(proxy.planar);
  EXPECT_NEAR(proxy.radius, 1.0, 0.02);  // radius 1, normals outward
  EXPECT_NEAR(Norm(proxy.centre + energy.origin()), 0.0, 1e-6);
  // The planar energy of the whole sphere is large: its normals point everywhere.
  const double total_area = std::accumulate(m.area.begin(), m.area.end(), 0.0);
  EXPECT_GT(EnergyFromSums(PlanarEnergy(m), one), total_area);
  // Ours, the normal fit, finds the same sphere as a curvature.
  SphereNormalFitEnergy::Sums normal_sums;
  const SphereNormalFitEnergy normal_fit(m);
  for (uint32_t f = 0; f < m.num_faces(); ++f) normal_sums += normal_fit.face_sums(f);
  EXPECT_NEAR(normal_fit.FitProxy(normal_sums).curvature, 1.0, 0.02);
}

TEST(EnergiesTest, PlanarAndSphereEnergiesAreZeroOnAPlane) {
  const TriangleMesh grid = testing::Grid(10);
  const FaceMeasures m = ComputeFaceMeasures(grid);
  const std::vector<ClusterId> one(m.num_faces(), ClusterId(0));
  EXPECT_NEAR(EnergyFromSums(PlanarEnergy(m), one), 0, 1e-12);
  // l. 1333: a planar cluster's sphere energy is 0 by rule (its centroids spread far).
  EXPECT_EQ(EnergyFromSums(SphereEnergy(m), one), 0);
  EXPECT_NEAR(EnergyFromSums(SphereNormalFitEnergy(m), one), 0, 1e-12);
  EXPECT_GT(EnergyFromSums(CvdEnergy(m), one), 1.0);
}

TEST(EnergiesTest, MwcvdWeightsFollowTheirFormulas) {
  // Two faces of area 1/2 with densities 1 and 3, centroids (1/3, 1/3) and (2/3, 2/3).
  const FaceMeasures m = ComputeFaceMeasures(testing::TwoTriangles());
  const std::vector<double> density = {1.0, 3.0};
  const MwcvdEnergy area(m, density, MwcvdEnergy::Weight::kArea);
  const MwcvdEnergy variance(m, density, MwcvdEnergy::Weight::kVariance);
  const MwcvdEnergy max(m, density, MwcvdEnergy::Weight::kMax, 10);
  auto both = [](const MwcvdEnergy& e) { return e.face_sums(0) + e.face_sums(1); };
  EXPECT_DOUBLE_EQ(area.ClusterWeight(both(area)), 0.5 * 1 + 0.5 * 3);
  EXPECT_DOUBLE_EQ(variance.ClusterWeight(both(variance)), 1 + (1 + 9) - 16.0 / 2);
  EXPECT_NEAR(max.ClusterWeight(both(max)), std::pow(1 + std::pow(3.0, 10), 0.1), 1e-12);
  EXPECT_DOUBLE_EQ(variance.ClusterWeight(variance.face_sums(1)), 1.0);
  // Eq. 3.23 by hand: masses rho A = 1/2 and 3/2, |g_0 - g_1|^2 = 2/9, so the CVD term is
  // (1/2 * 3/2) / 2 * 2/9 = 1/12, and E = w^A / 12 = 1/6. The density-weighted centroid is
  // (1/2 g_0 + 3/2 g_1) / 2 = (7/12, 7/12).
  EXPECT_NEAR(area.Energy(both(area)), 1.0 / 6, 1e-15);
  const MwcvdEnergy::Proxy proxy = area.FitProxy(both(area));
  EXPECT_NEAR((proxy.centroid + area.origin()).x, 7.0 / 12, 1e-15);
  EXPECT_NEAR((proxy.centroid + area.origin()).y, 7.0 / 12, 1e-15);
}

TEST(EnergiesTest, DensityIsHigherOnCreasesThanOnFlatParts) {
  // Two planes meeting at a right angle along a crease: faces at the crease see a normal
  // difference of sqrt(2), faces away from it none.
  TriangleMesh mesh = testing::Grid(6);
  for (size_t v = 0; v < mesh.num_vertices(); ++v) {
    float& x = mesh.positions[3 * v];
    float& z = mesh.positions[3 * v + 2];
    if (x > 3) {
      z = x - 3;
      x = 3;
    }
  }
  ASSERT_TRUE(ValidateMesh(mesh).ok());
  const FaceMeasures m = ComputeFaceMeasures(mesh);
  DensityOptions power;
  power.mapping = DensityOptions::Mapping::kPower;
  const std::vector<double> rho = ComputeFaceDensity(mesh, m, power);
  // Face 0 is in the flat corner (x in [0,1]); faces of column 2 touch the crease at x = 3.
  EXPECT_DOUBLE_EQ(rho[0], std::pow(1e-2, 2.0));
  EXPECT_GT(rho[2 * 2 + 1], rho[0] * 10);
  DensityOptions linear;
  linear.mapping = DensityOptions::Mapping::kLinear;
  linear.rho_max = 5;
  const std::vector<double> mapped = ComputeFaceDensity(mesh, m, linear);
  EXPECT_DOUBLE_EQ(*std::min_element(mapped.begin(), mapped.end()), 1.0);
  EXPECT_DOUBLE_EQ(*std::max_element(mapped.begin(), mapped.end()), 5.0);
}

// ---------------------------------------------------------------------------------------
// Each energy from its definition in the text, computed here face by face (not from the
// sums the energies keep), against what the library reports.

// A regular tetrahedron: every face meets the three others along an edge.
TriangleMesh RegularTetrahedron() {
  return testing::MakeMesh({1, 1, 1, 1, -1, -1, -1, 1, -1, -1, -1, 1},
                           {0, 1, 2, 0, 3, 1, 0, 2, 3, 1, 3, 2});
}

// The cube [-0.5, 0.5]^3 with each side split into 2 x 2 squares, two triangles each.
TriangleMesh SmallCube() { return testing::MakeCube(2).mesh; }

// Eq. 3.17 by brute force: for each vertex of f, every face that has that vertex.
std::vector<double> RawDensityByDefinition(const TriangleMesh& mesh, const FaceMeasures& m) {
  std::vector<double> raw(mesh.num_faces());
  for (size_t f = 0; f < mesh.num_faces(); ++f) {
    double sum = 0;
    int n = 0;
    for (int i = 0; i < 3; ++i) {
      const uint32_t v = mesh.indices[3 * f + i];
      for (size_t k = 0; k < mesh.num_faces(); ++k) {
        for (int c = 0; c < 3; ++c) {
          if (mesh.indices[3 * k + c] != v) continue;
          sum += Norm(m.unit_normal[f] - m.unit_normal[k]);
          ++n;
        }
      }
    }
    raw[f] = sum / n;
  }
  return raw;
}

TEST(DensityByDefinitionTest, TetrahedronCountsEdgeNeighboursTwiceAndItselfThrice) {
  const TriangleMesh tetrahedron = RegularTetrahedron();
  ASSERT_TRUE(ValidateMesh(tetrahedron).ok());
  const FaceMeasures m = ComputeFaceMeasures(tetrahedron);
  DensityOptions options;
  options.mapping = DensityOptions::Mapping::kPower;
  options.gamma = 1;
  const std::vector<double> rho = ComputeFaceDensity(tetrahedron, m, options);
  // Normals of a regular tetrahedron meet at acos(-1/3): |n_f - n_k| = sqrt(8/3). Around a
  // face: 9 incidences, itself 3 times (0) and each other face twice: rho' = 6/9 sqrt(8/3).
  for (double r : rho) EXPECT_NEAR(r, 2.0 / 3 * std::sqrt(8.0 / 3) + 1e-2, 1e-12);
}

TEST(DensityByDefinitionTest, BothMappingsAgreeWithEq317OnACube) {
  const TriangleMesh cube = SmallCube();
  ASSERT_TRUE(ValidateMesh(cube).ok());
  const FaceMeasures m = ComputeFaceMeasures(cube);
  const std::vector<double> raw = RawDensityByDefinition(cube, m);
  // Power mapping, the text's Delta = 1e-2 by default.
  DensityOptions power;
  power.mapping = DensityOptions::Mapping::kPower;
  EXPECT_EQ(power.delta, 1e-2);
  const std::vector<double> rho = ComputeFaceDensity(cube, m, power);
  for (size_t f = 0; f < raw.size(); ++f) {
    EXPECT_NEAR(rho[f], std::pow(raw[f] + 1e-2, power.gamma), 1e-12) << f;
  }
  // Linear mapping onto [1, rho^new].
  DensityOptions linear;
  linear.mapping = DensityOptions::Mapping::kLinear;
  linear.rho_max = 7;
  const std::vector<double> mapped = ComputeFaceDensity(cube, m, linear);
  const double lo = *std::min_element(raw.begin(), raw.end());
  const double hi = *std::max_element(raw.begin(), raw.end());
  ASSERT_GT(hi, lo);
  for (size_t f = 0; f < raw.size(); ++f) {
    EXPECT_NEAR(mapped[f], (hi - raw[f]) / (hi - lo) + 7 * (raw[f] - lo) / (hi - lo), 1e-12);
  }
}

TEST(DensityByDefinitionTest, DefaultsAreTheTextsPerEnergy) {
  const DensityOptions unset;
  const DensityOptions area = ResolveDensityOptions(MeshEnergyKind::kMwcvdArea, unset);
  const DensityOptions max = ResolveDensityOptions(MeshEnergyKind::kMwcvdMax, unset);
  const DensityOptions variance = ResolveDensityOptions(MeshEnergyKind::kMwcvdVariance, unset);
  const DensityOptions adaptive = ResolveDensityOptions(MeshEnergyKind::kCvdAdaptive, unset);
  EXPECT_EQ(area.mapping, DensityOptions::Mapping::kLinear);
  EXPECT_EQ(area.rho_max, 50);
  EXPECT_EQ(max.mapping, DensityOptions::Mapping::kLinear);
  EXPECT_EQ(max.rho_max, 50);
  EXPECT_EQ(variance.mapping, DensityOptions::Mapping::kLinear);
  EXPECT_EQ(variance.rho_max, 3);
  EXPECT_EQ(adaptive.mapping, DensityOptions::Mapping::kPower);
  EXPECT_EQ(adaptive.delta, 1e-2);
  // A user's choice stays.
  DensityOptions chosen;
  chosen.mapping = DensityOptions::Mapping::kPower;
  chosen.rho_max = 100;
  EXPECT_EQ(ResolveDensityOptions(MeshEnergyKind::kMwcvdArea, chosen).mapping,
            DensityOptions::Mapping::kPower);
  EXPECT_EQ(ResolveDensityOptions(MeshEnergyKind::kMwcvdArea, chosen).rho_max, 100);
}

// Eqs. 3.21, 3.22 and 3.24-3.26/3.28 in two passes over the faces.
double MwcvdByDefinition(const FaceMeasures& m, std::span<const double> rho,
                         std::span<const ClusterId> labels, MeshEnergyKind kind, double p) {
  std::map<uint32_t, std::vector<size_t>> clusters;
  for (size_t f = 0; f < labels.size(); ++f) clusters[labels[f].value()].push_back(f);
  double total = 0;
  for (const auto& [id, faces] : clusters) {
    double mass = 0, rho_sum = 0;
    Vec3 centre;
    for (size_t f : faces) {
      mass += rho[f] * m.area[f];
      centre += m.centroid[f] * (rho[f] * m.area[f]);
      rho_sum += rho[f];
    }
    centre = centre / mass;  // eq. 3.22
    const double rho_mean = rho_sum / faces.size();
    double weight = 0;
    if (kind == MeshEnergyKind::kMwcvdArea) {
      weight = mass;  // eq. 3.24
    } else if (kind == MeshEnergyKind::kMwcvdVariance) {
      weight = 1;  // eq. 3.25
      for (size_t f : faces) weight += (rho[f] - rho_mean) * (rho[f] - rho_mean);
    } else {
      double power = 0, largest = 0;  // eq. 3.28, which stands in for eq. 3.26
      for (size_t f : faces) {
        power += std::pow(rho[f], p);
        largest = std::max(largest, rho[f]);
      }
      weight = std::pow(power, 1 / p);
      EXPECT_GE(weight, largest);
      EXPECT_LE(weight, largest * std::pow(static_cast<double>(faces.size()), 1 / p) * 1.0001);
    }
    for (size_t f : faces) {  // eq. 3.21
      total += rho[f] * m.area[f] * weight * SquaredNorm(m.centroid[f] - centre);
    }
  }
  return total;
}

class MwcvdByDefinitionTest : public ::testing::TestWithParam<MeshEnergyKind> {};

TEST_P(MwcvdByDefinitionTest, ReportedEnergyIsEq321OnACubeAndOnARealMesh) {
  {
    const TriangleMesh mesh = SmallCube();
    const FaceMeasures m = ComputeFaceMeasures(mesh);
    MeshEnergyOptions options;
    options.kind = GetParam();
    // The density the energy uses: eq. 3.17 here, then the text's default linear mapping.
    const std::vector<double> raw = RawDensityByDefinition(mesh, m);
    const double lo = *std::min_element(raw.begin(), raw.end());
    const double hi = *std::max_element(raw.begin(), raw.end());
    ASSERT_GT(hi, lo);
    const double rho_new = options.kind == MeshEnergyKind::kMwcvdVariance ? 3 : 50;
    std::vector<double> rho(raw.size());
    for (size_t f = 0; f < raw.size(); ++f) {
      rho[f] = (hi - raw[f]) / (hi - lo) + rho_new * (raw[f] - lo) / (hi - lo);
    }
    for (uint32_t k : {1u, 3u, 7u}) {
      const std::vector<ClusterId> labels = RandomLabels(m.num_faces(), k, 11 * k);
      const double expected = MwcvdByDefinition(m, rho, labels, options.kind, options.mwcvd_p);
      ASSERT_GT(expected, 0);
      EXPECT_NEAR(MeshEnergyOfLabels(options, mesh, labels), expected, 1e-9 * expected) << k;
    }
  }
  // The elephant with the library's density (eq. 3.17 is checked above): the energy
  // reported from sums is still eq. 3.21 face by face.
  const RealMesh& elephant = Elephant();
  MeshEnergyOptions options;
  options.kind = GetParam();
  const std::vector<double> rho = EnergyFaceDensity(options, elephant.mesh, elephant.measures);
  ASSERT_EQ(rho.size(), elephant.measures.num_faces());
  const std::vector<ClusterId> labels = RandomLabels(elephant.measures.num_faces(), 40, 3);
  const double expected =
      MwcvdByDefinition(elephant.measures, rho, labels, options.kind, options.mwcvd_p);
  EXPECT_NEAR(MeshEnergyOfLabels(options, elephant.mesh, labels), expected, 1e-9 * expected);
}

// The energy the ML engine reports per level is eq. 3.21 of that level's labels.
TEST_P(MwcvdByDefinitionTest, EngineReportsEq321AtEveryLevelItStops) {
  const testing::LoadedMesh cube = testing::Load(testing::MakeCube(3).mesh);
  MeshEnergyOptions options;
  options.kind = GetParam();
  const std::vector<double> raw = RawDensityByDefinition(cube.mesh, cube.measures);
  const double lo = *std::min_element(raw.begin(), raw.end());
  const double hi = *std::max_element(raw.begin(), raw.end());
  const double rho_new = options.kind == MeshEnergyKind::kMwcvdVariance ? 3 : 50;
  std::vector<double> rho(raw.size());
  for (size_t f = 0; f < raw.size(); ++f) {
    rho[f] = (hi - raw[f]) / (hi - lo) + rho_new * (raw[f] - lo) / (hi - lo);
  }
  HierarchyLog log;
  ASSERT_TRUE(RunMultilevel(cube.problem(options.kind), MultilevelOptions{}, log).ok());
  for (size_t level : {size_t{10}, log.num_levels() / 2, log.num_levels() - 3}) {
    const std::vector<ClusterId> labels = *log.LabelsAt(level);
    const double expected =
        MwcvdByDefinition(cube.measures, rho, labels, options.kind, options.mwcvd_p);
    EXPECT_NEAR(log.energy(level), expected, 1e-9 * expected + 1e-15) << level;
  }
}

INSTANTIATE_TEST_SUITE_P(Weights, MwcvdByDefinitionTest,
                         ::testing::Values(MeshEnergyKind::kMwcvdArea,
                                           MeshEnergyKind::kMwcvdVariance,
                                           MeshEnergyKind::kMwcvdMax),
                         [](const auto& info) {
                           std::string name = MeshEnergyName(info.param);
                           std::replace(name.begin(), name.end(), '-', '_');
                           return name;
                         });

// Eqs. 3.40-3.42 with R_i from eq. 3.45, and the planar rule of l. 1333, cluster by cluster.
double SphereByDefinition(const FaceMeasures& m, std::span<const ClusterId> labels) {
  std::map<uint32_t, std::vector<size_t>> clusters;
  for (size_t f = 0; f < labels.size(); ++f) clusters[labels[f].value()].push_back(f);
  double total = 0;
  for (const auto& [id, faces] : clusters) {
    const double k = static_cast<double>(faces.size());
    Vec3 p_sum, n_sum;
    double pn_sum = 0;
    for (size_t f : faces) {
      p_sum += m.centroid[f];
      n_sum += m.unit_normal[f];
      pn_sum += Dot(m.centroid[f], m.unit_normal[f]);
    }
    if (std::abs(k * k - SquaredNorm(n_sum)) < 5e-5) continue;  // planar: E_i = 0
    const double radius = (k * pn_sum - Dot(p_sum, n_sum)) / (k * k - SquaredNorm(n_sum));
    Vec3 centre;  // eq. 3.42
    for (size_t f : faces) centre += m.centroid[f] - m.unit_normal[f] * radius;
    centre = centre / k;
    for (size_t f : faces) {  // eq. 3.40
      total += SquaredNorm(m.centroid[f] - m.unit_normal[f] * radius - centre);
    }
  }
  return total;
}

TEST(SphereByDefinitionTest, ReportedEnergyIsEq340WithTheRadiusOfEq345) {
  MeshEnergyOptions options;
  options.kind = MeshEnergyKind::kSphere;
  for (const TriangleMesh& mesh : {UnitSphere(2), SmallCube(), Elephant().mesh}) {
    const FaceMeasures m = ComputeFaceMeasures(mesh);
    for (uint32_t k : {1u, 2u, 9u}) {
      const std::vector<ClusterId> labels = RandomLabels(m.num_faces(), k, 5 * k);
      const double expected = SphereByDefinition(m, labels);
      ASSERT_GT(expected, 0);
      EXPECT_NEAR(MeshEnergyOfLabels(options, mesh, labels), expected, 1e-8 * expected) << k;
    }
  }
}

TEST(SphereByDefinitionTest, EngineReportsEq340AtEveryLevelItStops) {
  const testing::LoadedMesh sphere = testing::Load(UnitSphere(2));
  HierarchyLog log;
  ASSERT_TRUE(
      RunMultilevel(sphere.problem(MeshEnergyKind::kSphere), MultilevelOptions{}, log).ok());
  for (size_t level : {size_t{10}, log.num_levels() / 2, log.num_levels() - 2}) {
    const std::vector<ClusterId> labels = *log.LabelsAt(level);
    const double expected = SphereByDefinition(sphere.measures, labels);
    EXPECT_NEAR(log.energy(level), expected, 1e-8 * expected + 1e-12) << level;
  }
}

TEST(SphereByDefinitionTest, RadiusOfEq345MinimisesEq340) {
  const TriangleMesh sphere = UnitSphere(2);
  const FaceMeasures m = ComputeFaceMeasures(sphere);
  const SphereEnergy energy(m);
  SphereEnergy::Sums half;  // the faces above z = 0.2: a cap
  std::vector<size_t> cap;
  for (uint32_t f = 0; f < m.num_faces(); ++f) {
    if (m.centroid[f].z > 0.2) {
      half += energy.face_sums(f);
      cap.push_back(f);
    }
  }
  auto energy_at = [&](double radius) {
    Vec3 centre;
    for (size_t f : cap) centre += m.centroid[f] - m.unit_normal[f] * radius;
    centre = centre / static_cast<double>(cap.size());
    double e = 0;
    for (size_t f : cap) e += SquaredNorm(m.centroid[f] - m.unit_normal[f] * radius - centre);
    return e;
  };
  const double radius = energy.Radius(half);
  EXPECT_NEAR(energy.Energy(half), energy_at(radius), 1e-9);
  EXPECT_LT(energy_at(radius), energy_at(radius * 1.01));
  EXPECT_LT(energy_at(radius), energy_at(radius * 0.99));
  EXPECT_NEAR(radius, 1.0, 0.05);
}

TEST(SphereByDefinitionTest, PlanarClustersCostNothingAndMergeFirst) {
  const testing::SubdividedCube small = testing::MakeCube(2);  // 8 faces per side
  const TriangleMesh& cube = small.mesh;
  const FaceMeasures m = ComputeFaceMeasures(cube);
  const SphereEnergy energy(m);
  // Faces 0..7 are one side; face 40 is on another.
  ASSERT_EQ(small.side[7], small.side[0]);
  ASSERT_NE(small.side[40], small.side[0]);
  SphereEnergy::Sums side, pair, across;
  for (uint32_t f = 0; f < 8; ++f) side += energy.face_sums(f);
  pair = energy.face_sums(0) + energy.face_sums(1);
  EXPECT_TRUE(energy.IsPlanar(side));
  EXPECT_EQ(energy.Energy(side), 0);  // although its centroids spread over the side
  EXPECT_EQ(energy.MergeCost(pair, energy.face_sums(2)), 0);
  // A face of another side joins at a positive cost; a planar merge costs nothing, so ML
  // fits planes first.
  across = side + energy.face_sums(40);
  EXPECT_FALSE(energy.IsPlanar(across));
  EXPECT_GT(energy.MergeCost(side, energy.face_sums(40)), 0);
}

TEST(EnergiesTest, OptionsAreCheckedAndNamesParse) {
  for (const char* name : {"cvd", "cvd-adaptive", "mwcvd-area", "mwcvd-variance", "mwcvd-max",
                           "planar", "sphere", "sphere-normals"}) {
    absl::StatusOr<MeshEnergyKind> kind = ParseMeshEnergyKind(name);
    ASSERT_TRUE(kind.ok());
    EXPECT_STREQ(MeshEnergyName(*kind), name);
  }
  EXPECT_EQ(ParseMeshEnergyKind("l2").status().code(), absl::StatusCode::kInvalidArgument);
  MeshEnergyOptions options;
  EXPECT_TRUE(ValidateMeshEnergyOptions(options).ok());
  options.density.gamma = -1;
  EXPECT_THAT(std::string(ValidateMeshEnergyOptions(options).message()),
              ::testing::HasSubstr("gamma"));
  options = {};
  options.density.rho_max = 1;
  EXPECT_THAT(std::string(ValidateMeshEnergyOptions(options).message()),
              ::testing::HasSubstr("rho-max"));
}

}  // namespace
}  // namespace mlclust
