// The wire side of the registry (server/wire_registry.h, server/job_options.h) and the job
// runner's use of the plan (server/job_runner.h), without gRPC: a job goes straight to
// RunJob with an event channel that keeps what it is given.
#include "server/job_options.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <atomic>
#include <memory>
#include <vector>

#include "core/io/draco_codec.h"
#include "server/job_runner.h"
#include "server/wire_registry.h"
#include "tests/fixtures/job_runs.h"
#include "tests/fixtures/test_meshes.h"
#include "tests/fixtures/test_points.h"

namespace mlclust::server {
namespace {

using ::testing::HasSubstr;

TEST(WireRegistryTest, EveryWireValueHasARegistryEntryAndBack) {
  const google::protobuf::EnumDescriptor* algorithms = v1::Algorithm_descriptor();
  for (int i = 0; i < algorithms->value_count(); ++i) {
    const int value = algorithms->value(i)->number();
    if (value == 0) continue;
    EXPECT_TRUE(FindAlgorithmByWire(InputKind::kMesh, value) != nullptr ||
                FindAlgorithmByWire(InputKind::kPoints, value) != nullptr)
        << algorithms->value(i)->name();
  }
  for (const AlgorithmInfo& algorithm : Algorithms()) {
    EXPECT_TRUE(v1::Algorithm_IsValid(algorithm.wire)) << algorithm.name;
    // The wire name is the registry name, spelled as the enum spells it.
    std::string upper = algorithm.name == "lnkmeans" ? "LN_KMEANS" : algorithm.name;
    for (char& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    EXPECT_EQ(WireAlgorithmName(algorithm.wire), "ALGORITHM_" + upper);
  }
  const google::protobuf::EnumDescriptor* energies = v1::Energy_descriptor();
  for (int i = 0; i < energies->value_count(); ++i) {
    const int value = energies->value(i)->number();
    if (value == 0) continue;
    EXPECT_TRUE(FindEnergyByWire(InputKind::kMesh, value) != nullptr ||
                FindEnergyByWire(InputKind::kPoints, value) != nullptr)
        << energies->value(i)->name();
  }
  for (const EnergyInfo& energy : Energies()) {
    if (energy.wire == 0) continue;
    std::string upper = energy.name;
    for (char& c : upper) {
      c = c == '-' ? '_' : static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    }
    EXPECT_EQ(WireEnergyName(energy.wire), "ENERGY_" + upper);
  }
}

TEST(WireRegistryTest, UnknownValuesAreNamedByNumber) {
  absl::StatusOr<const AlgorithmInfo*> algorithm = AlgorithmFromWire(InputKind::kMesh, 99);
  EXPECT_EQ(algorithm.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(algorithm.status().message()), HasSubstr("algorithm 99 "));
  absl::StatusOr<const EnergyInfo*> energy = EnergyFromWire(InputKind::kMesh, 42);
  EXPECT_EQ(energy.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(energy.status().message()), HasSubstr("energy: 42 "));
  // Known, but for the other input: UNIMPLEMENTED, listing what there is.
  algorithm = AlgorithmFromWire(InputKind::kMesh, v1::ALGORITHM_KMEANS);
  EXPECT_EQ(algorithm.status().code(), absl::StatusCode::kUnimplemented);
  EXPECT_THAT(std::string(algorithm.status().message()),
              HasSubstr("available: ALGORITHM_HC, ALGORITHM_ML, ALGORITHM_PML, ALGORITHM_EMLO, "
                        "ALGORITHM_BB, ALGORITHM_VSA"));
  energy = EnergyFromWire(InputKind::kPoints, v1::ENERGY_PLANAR);
  EXPECT_THAT(std::string(energy.status().message()), HasSubstr("available: ENERGY_VARIANCE"));
}

v1::JobSpec MeshSpec(v1::Algorithm algorithm, uint32_t clusters = 0) {
  v1::JobSpec spec;
  spec.set_input_kind(v1::INPUT_KIND_DRACO_MESH);
  spec.set_algorithm(algorithm);
  spec.set_clusters(clusters);
  return spec;
}

TEST(PlanWireJobTest, DefaultsAndOptions) {
  // No algorithm: ML for meshes (issue 11 item 6) and points.
  absl::StatusOr<JobPlan> plan = PlanWireJob(MeshSpec(v1::ALGORITHM_UNSPECIFIED));
  ASSERT_TRUE(plan.ok()) << plan.status();
  EXPECT_EQ(plan->algorithm->name, "ml");
  EXPECT_EQ(plan->multilevel.optimizer, MultilevelOptions::Optimizer::kEmlo);
  v1::JobSpec points;
  points.set_input_kind(v1::INPUT_KIND_POINTS_F32);
  plan = PlanWireJob(points);
  ASSERT_TRUE(plan.ok());
  EXPECT_EQ(plan->algorithm->name, "ml");
  EXPECT_EQ(plan->energy->name, "variance");

  // A job without 'density' keeps the energy's own mapping.
  v1::JobSpec spec = MeshSpec(v1::ALGORITHM_EMLO, 10);
  spec.set_energy(v1::ENERGY_MWCVD_AREA);
  plan = PlanWireJob(spec);
  ASSERT_TRUE(plan.ok());
  EXPECT_EQ(plan->mesh_energy.kind, MeshEnergyKind::kMwcvdArea);
  EXPECT_EQ(plan->mesh_energy.density.mapping, DensityOptions::Mapping::kDefault);
  (*spec.mutable_options())["density"] = "power";
  (*spec.mutable_options())["init"] = "random";
  (*spec.mutable_options())["level"] = "2";
  spec.set_seed(9);
  plan = PlanWireJob(spec);
  ASSERT_TRUE(plan.ok());
  EXPECT_EQ(plan->mesh_energy.density.mapping, DensityOptions::Mapping::kPower);
  EXPECT_EQ(plan->seeds.method, SeedOptions::Method::kRandom);
  EXPECT_EQ(plan->seeds.level, 2u);
  EXPECT_EQ(plan->seeds.seed, 9u);
  EXPECT_EQ(plan->seeds.clusters, 10u);

  // Device: checked when planned, for points as for meshes.
  points.set_device("tpu");
  EXPECT_THAT(std::string(PlanWireJob(points).status().message()), HasSubstr("device"));
}

using Outcome = testing::JobRun;
using testing::CubeDraco;
using testing::RunOne;

std::string BlobBytes(const PointSet& points) {
  return std::string(reinterpret_cast<const char*>(points.values.data()),
                     points.values.size() * sizeof(float));
}

TEST(JobRunnerTest, ProgressNamesTheDeviceOfEveryStage) {
  for (v1::Algorithm algorithm : {v1::ALGORITHM_ML, v1::ALGORITHM_EMLO, v1::ALGORITHM_VSA}) {
    v1::JobSpec spec = MeshSpec(algorithm, algorithm == v1::ALGORITHM_ML ? 0 : 6);
    if (algorithm == v1::ALGORITHM_VSA) spec.set_energy(v1::ENERGY_PLANAR);
    Outcome outcome = RunOne(spec, CubeDraco());
    ASSERT_TRUE(outcome.result.ok()) << outcome.result.status();
    std::vector<std::string> stages;
    for (const v1::JobEvent& event : outcome.events) {
      if (!event.has_progress()) continue;
      EXPECT_EQ(event.progress().device(), "cpu") << event.progress().stage();
      if (stages.empty() || stages.back() != event.progress().stage()) {
        stages.push_back(event.progress().stage());
      }
    }
    if (algorithm == v1::ALGORITHM_ML) {
      EXPECT_THAT(stages, ::testing::ElementsAre("decode", "measures", "cluster"));
    } else {
      EXPECT_THAT(stages, ::testing::ElementsAre("decode", "measures", "seed", "cluster"));
      EXPECT_EQ(outcome.result->done.final_clusters(), 6u);
      EXPECT_EQ(outcome.result->done.levels(), 2u);
    }
    EXPECT_EQ(outcome.result->done.device(), "cpu");
  }
  // No GPU here: device gpu is refused before anything runs.
  v1::JobSpec spec = MeshSpec(v1::ALGORITHM_HC);
  spec.set_device("gpu");
  Outcome outcome = RunOne(spec, CubeDraco());
  EXPECT_EQ(outcome.result.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_TRUE(outcome.events.empty());
}

TEST(JobRunnerTest, KmeansReportsItsClustersAndTheSeedingAsLevelZero) {
  const testing::Blobs blobs = testing::GaussianBlobs(5, 50, 12, 4);
  v1::JobSpec spec;
  spec.set_input_kind(v1::INPUT_KIND_POINTS_F32);
  spec.set_point_dims(3);
  spec.set_algorithm(v1::ALGORITHM_KMEANS);
  spec.set_clusters(5);
  spec.set_seed(2);
  Outcome outcome = RunOne(spec, BlobBytes(blobs.points));
  ASSERT_TRUE(outcome.result.ok()) << outcome.result.status();
  EXPECT_EQ(outcome.result->done.final_clusters(), 5u);
  EXPECT_EQ(outcome.result->done.levels(), 2u);
  // Level 0: every point at its nearest k-means++ centre, as SeedPointClusters seeds.
  const std::vector<ClusterId> seeded = *SeedPointClusters(blobs.points, 5, true, 2);
  std::vector<uint32_t> snapshot;
  for (const v1::JobEvent& event : outcome.events) {
    if (event.has_snapshot()) {
      snapshot.assign(event.snapshot().labels().begin(), event.snapshot().labels().end());
      EXPECT_EQ(event.snapshot().cluster_count(), 5u);
    }
  }
  ASSERT_EQ(snapshot.size(), seeded.size());
  for (size_t i = 0; i < seeded.size(); ++i) EXPECT_EQ(snapshot[i], seeded[i].value()) << i;
  // Options the registry does not list for k-means are refused, naming them.
  (*spec.mutable_options())["optimizer"] = "none";
  outcome = RunOne(spec, BlobBytes(blobs.points));
  EXPECT_THAT(std::string(outcome.result.status().message()),
              HasSubstr("option optimizer is not known for kmeans"));
  // grid is k-means' since its voxel start (init grid), and only with it.
  spec.mutable_options()->erase("optimizer");
  (*spec.mutable_options())["grid"] = "4";
  outcome = RunOne(spec, BlobBytes(blobs.points));
  EXPECT_THAT(std::string(outcome.result.status().message()), HasSubstr("applies to init grid"));
}

TEST(JobRunnerTest, ClustersAboveTheElementCountAreRefused) {
  Outcome outcome = RunOne(MeshSpec(v1::ALGORITHM_HC, 100000), CubeDraco());
  EXPECT_EQ(outcome.result.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(outcome.result.status().message()), HasSubstr("clusters: 100000"));
}

}  // namespace
}  // namespace mlclust::server
