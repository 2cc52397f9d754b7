#include "core/cluster/vsa.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <atomic>
#include <set>

#include "core/energy/energies.h"
#include "core/io/mesh_io.h"
#include "core/mesh/face_measures.h"
#include "tests/fixtures/labels.h"
#include "tests/fixtures/test_meshes.h"

namespace mlclust {
namespace {

using ::testing::HasSubstr;
using Seeding = VsaOptions::Seeding;

constexpr Seeding kAllSeedings[] = {Seeding::kRandom, Seeding::kIncremental,
                                    Seeding::kHierarchical};

using Loaded = testing::LoadedMesh;
using testing::Load;

const Loaded& Elephant() {
  static const Loaded* elephant =
      new Loaded(Load(*ReadMeshFile(testing::DataPath("elephant.off"))));
  return *elephant;
}

TriangleMesh Cube(int n = 3, float offset = 0) { return testing::IntegerCube(n, offset); }

// Two cubes side by side, not touching: a mesh of two connected components.
TriangleMesh TwoCubes() {
  TriangleMesh a = Cube(2), b = Cube(2, 10);
  const uint32_t shift = static_cast<uint32_t>(a.num_vertices());
  a.positions.insert(a.positions.end(), b.positions.begin(), b.positions.end());
  for (uint32_t v : b.indices) a.indices.push_back(v + shift);
  return a;
}

using testing::DistinctLabels;
using testing::PiecesPerCluster;

// Checks what every result must satisfy: exactly k regions numbered 0..k-1, each one
// edge-connected piece holding its seed, and the reported energy equal to the planar
// energy of the labels.
void ExpectValidPartition(const Loaded& l, const VsaResult& result, uint32_t k) {
  ASSERT_EQ(result.labels.size(), l.mesh.num_faces());
  const std::set<uint32_t> regions = DistinctLabels(result.labels);
  ASSERT_EQ(regions.size(), k);
  EXPECT_EQ(*regions.rbegin(), k - 1);
  const std::vector<uint32_t> pieces = PiecesPerCluster(l.adjacency, result.labels, k);
  for (uint32_t r = 0; r < k; ++r) EXPECT_EQ(pieces[r], 1u) << "region " << r;
  ASSERT_EQ(result.seeds.size(), k);
  ASSERT_EQ(result.proxies.size(), k);
  for (uint32_t r = 0; r < k; ++r) {
    EXPECT_EQ(result.labels[result.seeds[r].value()], ClusterId(r));
    EXPECT_NEAR(Norm(result.proxies[r]), 1.0, 1e-12);
  }
  const PlanarEnergy planar(l.measures);
  const double from_sums = EnergyFromSums(planar, result.labels);
  EXPECT_NEAR(result.energy, from_sums, 1e-9 * std::max(1.0, from_sums));
  EXPECT_NEAR(result.energy, EnergyFromProxies(planar, result.labels),
              1e-9 * std::max(1.0, from_sums));
}

VsaOptions Options(uint32_t k, Seeding seeding, uint64_t seed = 1) {
  VsaOptions options;
  options.clusters = k;
  options.seeding = seeding;
  options.seed = seed;
  return options;
}

// The side of the cube a face lies on: its normal's axis and sign, 0..5.
int Side(const Loaded& l, uint32_t face) {
  const Vec3& n = l.measures.unit_normal[face];
  const double c[3] = {n.x, n.y, n.z};
  for (int axis = 0; axis < 3; ++axis) {
    if (std::abs(c[axis]) > 0.5) return 2 * axis + (c[axis] > 0);
  }
  return -1;
}

// The cube at k = 6: one region per side, energy 0, for every seeding and seed. Lloyd
// alone cannot get there from two seeds on one side (both fit it exactly and neither is
// moved off it), which random seeding gives for most seeds and error diffusion can give
// too; teleportation merges such a pair and reseeds the worst region. (With one square
// per side, n = 1, random seeding can end with four regions of one triangle on each of two
// sides, where no merge passes teleportation's test; n >= 2 leaves no such minimum.)
TEST(VsaTest, CubeGivesOneRegionPerSideAndZeroEnergy) {
  for (int n : {1, 2, 3, 4}) {
    const Loaded l = Load(Cube(n));
    ASSERT_EQ(l.mesh.num_faces(), 12u * n * n);
    for (Seeding seeding : kAllSeedings) {
      if (seeding == Seeding::kRandom && n == 1) continue;
      for (uint64_t seed = 1; seed <= (seeding == Seeding::kRandom ? 100 : 1); ++seed) {
        SCOPED_TRACE(::testing::Message()
                     << "n " << n << " " << VsaSeedingName(seeding) << " seed " << seed);
        absl::StatusOr<VsaResult> result =
            RunVsa(l.problem(MeshEnergyKind::kPlanar), Options(6, seeding, seed));
        ASSERT_TRUE(result.ok()) << result.status();
        ExpectValidPartition(l, *result, 6);
        EXPECT_NEAR(result->energy, 0.0, 1e-9);
        std::set<std::pair<uint32_t, int>> region_sides;
        for (uint32_t f = 0; f < l.mesh.num_faces(); ++f) {
          region_sides.insert({result->labels[f].value(), Side(l, f)});
        }
        EXPECT_EQ(region_sides.size(), 6u);  // each region one side, each side one region
      }
    }
  }
}

TEST(VsaTest, WithoutTeleportationLloydStaysInALocalMinimum) {
  const Loaded l = Load(Cube(3));
  int stuck = 0, exact = 0;
  for (uint64_t seed = 1; seed <= 50; ++seed) {
    VsaOptions options = Options(6, Seeding::kRandom, seed);
    options.teleport = false;
    absl::StatusOr<VsaResult> result = RunVsa(l.problem(MeshEnergyKind::kPlanar), options);
    ASSERT_TRUE(result.ok()) << result.status();
    ExpectValidPartition(l, *result, 6);
    EXPECT_EQ(result->teleports, 0u);
    std::set<int> seed_sides;
    for (FaceId s : result->seeds) seed_sides.insert(Side(l, s.value()));
    if (seed_sides.size() == 6) {
      ++exact;
      EXPECT_NEAR(result->energy, 0.0, 1e-9) << "seed " << seed;
    } else {
      ++stuck;
      EXPECT_GT(result->energy, 1.0) << "seed " << seed;  // a side shared: far from 0
      EXPECT_TRUE(result->converged);
    }
  }
  EXPECT_GT(stuck, 0);
}

TEST(VsaTest, TwoComponentsGetARegionEachAndKBelowComponentsIsRefused) {
  const Loaded l = Load(TwoCubes());
  ASSERT_EQ(CountFaceComponents(l.adjacency), 2u);
  for (Seeding seeding : kAllSeedings) {
    for (uint32_t k : {2u, 3u, 12u}) {
      SCOPED_TRACE(::testing::Message() << "k " << k << " " << VsaSeedingName(seeding));
      absl::StatusOr<VsaResult> result =
          RunVsa(l.problem(MeshEnergyKind::kPlanar), Options(k, seeding));
      ASSERT_TRUE(result.ok()) << result.status();
      ExpectValidPartition(l, *result, k);
      // No region spans both cubes (the faces of the first cube come first).
      const size_t half = l.mesh.num_faces() / 2;
      std::set<uint32_t> first, second;
      for (size_t f = 0; f < l.mesh.num_faces(); ++f) {
        (f < half ? first : second).insert(result->labels[f].value());
      }
      for (uint32_t r : first) EXPECT_EQ(second.count(r), 0u) << "region " << r;
      EXPECT_FALSE(first.empty());
      EXPECT_FALSE(second.empty());
    }
    // With k = 12 both cubes are cut into their six sides.
    absl::StatusOr<VsaResult> twelve =
        RunVsa(l.problem(MeshEnergyKind::kPlanar), Options(12, seeding, 2));
    ASSERT_TRUE(twelve.ok());
    if (seeding != Seeding::kRandom) {
      EXPECT_NEAR(twelve->energy, 0.0, 1e-9);
    }
  }
  absl::StatusOr<VsaResult> one =
      RunVsa(l.problem(MeshEnergyKind::kPlanar), Options(1, Seeding::kHierarchical));
  EXPECT_EQ(one.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(one.status().message(), HasSubstr("clusters"));
  EXPECT_THAT(one.status().message(), HasSubstr("2 connected components"));
}

TEST(VsaTest, ExactlyKConnectedRegionsOnARealMesh) {
  const Loaded& l = Elephant();
  for (Seeding seeding : kAllSeedings) {
    for (uint32_t k : {1u, 7u, 50u, 300u}) {
      if (seeding == Seeding::kIncremental && k > 50) continue;  // k x 5 iterations
      SCOPED_TRACE(::testing::Message() << "k " << k << " " << VsaSeedingName(seeding));
      absl::StatusOr<VsaResult> result =
          RunVsa(l.problem(MeshEnergyKind::kPlanar), Options(k, seeding));
      ASSERT_TRUE(result.ok()) << result.status();
      ExpectValidPartition(l, *result, k);
      EXPECT_LE(result->energy, result->initial_energy);
      if (k > 1) {
        EXPECT_GT(result->seeding_iterations, 0u);
      }
    }
  }
}

// A full run hands back the seeding's partition as initial_labels: the labels (and
// energy) of a run with no Lloyd iteration, so the seeding need not run twice.
TEST(VsaTest, InitialLabelsAreTheSeedingsPartition) {
  const Loaded& l = Elephant();
  for (Seeding seeding : kAllSeedings) {
    SCOPED_TRACE(VsaSeedingName(seeding));
    VsaOptions options = Options(40, seeding, 3);
    absl::StatusOr<VsaResult> full = RunVsa(l.problem(MeshEnergyKind::kPlanar), options);
    ASSERT_TRUE(full.ok()) << full.status();
    options.iterations = 0;
    absl::StatusOr<VsaResult> seeded = RunVsa(l.problem(MeshEnergyKind::kPlanar), options);
    ASSERT_TRUE(seeded.ok()) << seeded.status();
    EXPECT_EQ(full->initial_labels, seeded->labels);
    EXPECT_EQ(full->initial_energy, seeded->energy);
    EXPECT_EQ(seeded->initial_labels, seeded->labels);
    EXPECT_GT(full->iterations, 0u);
    EXPECT_LE(full->energy, full->initial_energy);
  }
}

// Without relaxations or iterations the seeding's partition comes back as it is; it is a
// flood's all the same, so its regions are connected.
TEST(VsaTest, NoIterationsStillGiveConnectedRegions) {
  const Loaded& l = Elephant();
  for (Seeding seeding : kAllSeedings) {
    SCOPED_TRACE(VsaSeedingName(seeding));
    VsaOptions options = Options(30, seeding);
    options.inner_iterations = 0;
    options.iterations = 0;
    absl::StatusOr<VsaResult> result = RunVsa(l.problem(MeshEnergyKind::kPlanar), options);
    ASSERT_TRUE(result.ok()) << result.status();
    ExpectValidPartition(l, *result, 30);
    EXPECT_EQ(result->iterations, 0u);
    EXPECT_EQ(result->seeding_iterations, 1u);
    EXPECT_EQ(result->energy, result->initial_energy);
  }
}

// Every face its own region (k = faces) and k = faces - 1 are reachable.
TEST(VsaTest, KUpToTheFaceCount) {
  const Loaded l = Load(testing::Grid(3));
  const uint32_t faces = static_cast<uint32_t>(l.mesh.num_faces());
  for (Seeding seeding : kAllSeedings) {
    for (uint32_t k : {faces - 1, faces}) {
      SCOPED_TRACE(::testing::Message() << "k " << k << " " << VsaSeedingName(seeding));
      absl::StatusOr<VsaResult> result =
          RunVsa(l.problem(MeshEnergyKind::kPlanar), Options(k, seeding));
      ASSERT_TRUE(result.ok()) << result.status();
      ExpectValidPartition(l, *result, k);
      EXPECT_NEAR(result->energy, 0.0, 1e-12);  // a plane
    }
  }
}

// Running with 0, 1, ..., N iterations: the returned energy never rises, since an
// iteration's partition is kept only if it is better than the best so far; and the
// callback sees every iteration with the energy of that iteration's partition.
TEST(VsaTest, EnergyNeverIncreasesWithMoreIterations) {
  const Loaded& l = Elephant();
  for (Seeding seeding : {Seeding::kRandom, Seeding::kHierarchical}) {
    SCOPED_TRACE(VsaSeedingName(seeding));
    VsaOptions options = Options(40, seeding);
    std::vector<double> reported;
    options.iterations = 20;
    options.on_iteration = [&](uint32_t iteration, double energy) {
      EXPECT_EQ(iteration, reported.size() + 1);
      reported.push_back(energy);
    };
    absl::StatusOr<VsaResult> full = RunVsa(l.problem(MeshEnergyKind::kPlanar), options);
    ASSERT_TRUE(full.ok());
    ASSERT_EQ(reported.size(), full->iterations);
    ASSERT_GE(reported.size(), 2u);
    EXPECT_DOUBLE_EQ(full->energy, std::min(full->initial_energy,
                                            *std::min_element(reported.begin(), reported.end())));
    options.on_iteration = nullptr;
    double previous = full->initial_energy;
    for (uint32_t n = 0; n <= full->iterations; ++n) {
      options.iterations = n;
      absl::StatusOr<VsaResult> result = RunVsa(l.problem(MeshEnergyKind::kPlanar), options);
      ASSERT_TRUE(result.ok());
      EXPECT_LE(result->energy, previous) << n << " iterations";
      if (n > 0) {
        // The partition returned is the best of the first n, as reported by the callback.
        const double best = std::min(full->initial_energy,
                                     *std::min_element(reported.begin(), reported.begin() + n));
        EXPECT_DOUBLE_EQ(result->energy, best) << n << " iterations";
      } else {
        EXPECT_DOUBLE_EQ(result->energy, result->initial_energy);
      }
      previous = result->energy;
    }
    // Lloyd iterations improve on the seeding.
    EXPECT_LT(full->energy, full->initial_energy);
  }
}

TEST(VsaTest, StopsAtAFixedPointAndOnASmallDecrease) {
  // On the cube Lloyd ends in a fixed point (on real meshes it mostly ends in a cycle of
  // partitions instead, and then all iterations run).
  const Loaded cube = Load(Cube(3));
  VsaOptions options = Options(6, Seeding::kHierarchical);
  options.iterations = 1000;
  absl::StatusOr<VsaResult> result = RunVsa(cube.problem(MeshEnergyKind::kPlanar), options);
  ASSERT_TRUE(result.ok());
  EXPECT_TRUE(result->converged);
  EXPECT_LT(result->iterations, 10u);
  // Running on past the fixed point changes nothing.
  VsaOptions more = options;
  more.iterations = result->iterations + 5;
  absl::StatusOr<VsaResult> again = RunVsa(cube.problem(MeshEnergyKind::kPlanar), more);
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(again->labels, result->labels);
  EXPECT_EQ(again->iterations, result->iterations);

  const Loaded& l = Elephant();
  options = Options(20, Seeding::kHierarchical);
  options.iterations = 1000;
  // A large tolerance stops after the first iteration that gains less than it.
  std::vector<double> energies;
  options.min_relative_decrease = 0.05;
  options.teleport = false;
  options.on_iteration = [&](uint32_t, double energy) { energies.push_back(energy); };
  absl::StatusOr<VsaResult> early = RunVsa(l.problem(MeshEnergyKind::kPlanar), options);
  ASSERT_TRUE(early.ok());
  EXPECT_TRUE(early->converged);
  ASSERT_EQ(energies.size(), early->iterations);
  double previous = early->initial_energy;
  for (size_t i = 0; i + 1 < energies.size(); ++i) {
    EXPECT_GE(previous - energies[i], 0.05 * previous);
    previous = energies[i];
  }
  EXPECT_LT(previous - energies.back(), 0.05 * previous);
}

TEST(VsaTest, SameSeedSameResultOtherSeedOtherResult) {
  const Loaded& l = Elephant();
  for (Seeding seeding : kAllSeedings) {
    SCOPED_TRACE(VsaSeedingName(seeding));
    const uint32_t k = seeding == Seeding::kIncremental ? 20 : 100;
    absl::StatusOr<VsaResult> a =
        RunVsa(l.problem(MeshEnergyKind::kPlanar), Options(k, seeding, 7));
    absl::StatusOr<VsaResult> b =
        RunVsa(l.problem(MeshEnergyKind::kPlanar), Options(k, seeding, 7));
    ASSERT_TRUE(a.ok() && b.ok());
    EXPECT_EQ(a->labels, b->labels);
    EXPECT_EQ(a->energy, b->energy);
    if (seeding == Seeding::kRandom) {
      absl::StatusOr<VsaResult> c =
          RunVsa(l.problem(MeshEnergyKind::kPlanar), Options(k, seeding, 8));
      ASSERT_TRUE(c.ok());
      EXPECT_NE(a->labels, c->labels);
    }
  }
}

TEST(VsaTest, BadOptionsAreRefusedNamingTheOption) {
  const Loaded& l = Elephant();
  const uint32_t faces = static_cast<uint32_t>(l.mesh.num_faces());
  absl::StatusOr<VsaResult> cvd = RunVsa(l.problem(MeshEnergyKind::kCvd), Options(10, {}));
  EXPECT_EQ(cvd.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(cvd.status().message(), HasSubstr("energy"));
  for (uint32_t k : {0u, faces + 1}) {
    absl::StatusOr<VsaResult> bad =
        RunVsa(l.problem(MeshEnergyKind::kPlanar), Options(k, Seeding::kHierarchical));
    EXPECT_EQ(bad.status().code(), absl::StatusCode::kInvalidArgument) << k;
    EXPECT_THAT(bad.status().message(), HasSubstr("clusters")) << k;
  }
  VsaOptions negative = Options(10, Seeding::kHierarchical);
  negative.min_relative_decrease = -1;
  EXPECT_EQ(RunVsa(l.problem(MeshEnergyKind::kPlanar), negative).status().code(),
            absl::StatusCode::kInvalidArgument);
  MeshProblem empty;
  EXPECT_EQ(RunVsa(empty, Options(10, {})).status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_FALSE(ParseVsaSeeding("lloyd").ok());
  for (Seeding seeding : kAllSeedings) {
    EXPECT_EQ(*ParseVsaSeeding(VsaSeedingName(seeding)), seeding);
  }
}

TEST(VsaTest, ACancelFlagReturnsCancelled) {
  const Loaded& elephant = Elephant();
  std::atomic<bool> cancel{true};
  VsaOptions options;
  options.clusters = 20;
  options.cancel = &cancel;
  EXPECT_EQ(RunVsa(elephant.problem(MeshEnergyKind::kPlanar), options).status().code(),
            absl::StatusCode::kCancelled);
  // Set after the second Lloyd iteration: no third one runs.
  cancel = false;
  uint32_t iterations = 0;
  options.on_iteration = [&](uint32_t iteration, double) {
    iterations = iteration;
    if (iteration == 2) cancel = true;
  };
  EXPECT_EQ(RunVsa(elephant.problem(MeshEnergyKind::kPlanar), options).status().code(),
            absl::StatusCode::kCancelled);
  EXPECT_EQ(iterations, 2u);
}

}  // namespace
}  // namespace mlclust
