#include "core/energy/energies.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <map>
#include <numeric>
#include <random>

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
                                           MeshEnergyKind::kSphere),
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
  const double total_area = std::accumulate(m.area.begin(), m.area.end(), 0.0);
  // Chords put centroids slightly inside the sphere: small, not zero, misfit.
  EXPECT_LT(EnergyFromSums(energy, one), 1e-3 * total_area);
  SphereEnergy::Sums sums;
  for (uint32_t f = 0; f < m.num_faces(); ++f) sums += energy.face_sums(f);
  const SphereEnergy::Proxy proxy = energy.FitProxy(sums);
  EXPECT_NEAR(proxy.curvature, 1.0, 0.02);  // radius 1, normals outward
  // The planar energy of the whole sphere is large: its normals point everywhere.
  EXPECT_GT(EnergyFromSums(PlanarEnergy(m), one), total_area);
}

TEST(EnergiesTest, PlanarAndSphereEnergiesAreZeroOnAPlane) {
  const TriangleMesh grid = testing::Grid(10);
  const FaceMeasures m = ComputeFaceMeasures(grid);
  const std::vector<ClusterId> one(m.num_faces(), ClusterId(0));
  EXPECT_NEAR(EnergyFromSums(PlanarEnergy(m), one), 0, 1e-12);
  EXPECT_NEAR(EnergyFromSums(SphereEnergy(m), one), 0, 1e-12);
  EXPECT_GT(EnergyFromSums(CvdEnergy(m), one), 1.0);
}

TEST(EnergiesTest, MwcvdWeightsFollowTheirFormulas) {
  // Two faces of area 1/2 with densities 1 and 3.
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
  // Energy = weight x uniform CVD term: 1/18 for these two faces (see the HC test).
  EXPECT_NEAR(area.Energy(both(area)), 2.0 / 18, 1e-15);
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
  const std::vector<double> rho = ComputeFaceDensity(mesh, m, power);
  // Face 0 is in the flat corner (x in [0,1]); faces of column 2 touch the crease at x = 3.
  EXPECT_DOUBLE_EQ(rho[0], std::pow(0.1, 2.0));
  EXPECT_GT(rho[2 * 2 + 1], rho[0] * 10);
  DensityOptions linear;
  linear.mapping = DensityOptions::Mapping::kLinear;
  linear.rho_max = 5;
  const std::vector<double> mapped = ComputeFaceDensity(mesh, m, linear);
  EXPECT_DOUBLE_EQ(*std::min_element(mapped.begin(), mapped.end()), 1.0);
  EXPECT_DOUBLE_EQ(*std::max_element(mapped.begin(), mapped.end()), 5.0);
}

TEST(EnergiesTest, OptionsAreCheckedAndNamesParse) {
  for (const char* name :
       {"cvd", "cvd-adaptive", "mwcvd-area", "mwcvd-variance", "mwcvd-max", "planar", "sphere"}) {
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
