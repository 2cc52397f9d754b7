// JobSpec.polygon_triangle_counts (issue 13) in the plan and the job runner, without
// gRPC: which algorithms and devices take polygons, bad counts refused naming the polygon,
// and a run whose levels never split a polygon.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <atomic>
#include <memory>
#include <string>
#include <vector>

#include "core/io/draco_codec.h"
#include "server/job_options.h"
#include "server/job_runner.h"
#include "tests/fixtures/job_runs.h"

namespace mlclust::server {
namespace {

using ::testing::HasSubstr;

using testing::JobRun;

v1::JobSpec PolygonSpec(v1::Algorithm algorithm, uint32_t clusters,
                        const std::vector<uint32_t>& counts) {
  v1::JobSpec spec;
  spec.set_input_kind(v1::INPUT_KIND_DRACO_MESH);
  spec.set_algorithm(algorithm);
  spec.set_clusters(clusters);
  for (uint32_t count : counts) spec.add_polygon_triangle_counts(count);
  return spec;
}

// A job on the cube of 6 x 4 x 4 squares, two triangles each in square order: 96 polygons.
JobRun RunOne(const v1::JobSpec& spec) { return testing::RunOne(spec, testing::CubeDraco()); }

TEST(PolygonJobTest, PlanTakesPolygonsForTheCpuDriversOnly) {
  const std::vector<uint32_t> squares(96, 2);
  for (v1::Algorithm algorithm : {v1::ALGORITHM_ML, v1::ALGORITHM_HC, v1::ALGORITHM_PML,
                                  v1::ALGORITHM_EMLO, v1::ALGORITHM_BB}) {
    // Every stage on the CPU, on a machine with a GPU too (the device policy's rule).
    absl::StatusOr<JobPlan> plan = server::PlanJobOnDevice(PolygonSpec(algorithm, 6, squares),
                                                           DeviceCaps(true, false, "NVIDIA H100"));
    ASSERT_TRUE(plan.ok()) << plan.status();
    EXPECT_FALSE(UsesGpu(*plan));
  }
  v1::JobSpec vsa = PolygonSpec(v1::ALGORITHM_VSA, 6, squares);
  vsa.set_energy(v1::ENERGY_PLANAR);
  EXPECT_THAT(std::string(PlanWireJob(vsa).status().message()), HasSubstr("not vsa"));
  v1::JobSpec gpu = PolygonSpec(v1::ALGORITHM_ML, 6, squares);
  gpu.set_device("gpu");
  const absl::Status refused =
      server::PlanJobOnDevice(gpu, DeviceCaps(true, false, "NVIDIA H100")).status();
  EXPECT_EQ(refused.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(std::string(refused.message()), HasSubstr("per-polygon clustering"));
  v1::JobSpec points = PolygonSpec(v1::ALGORITHM_ML, 6, squares);
  points.set_input_kind(v1::INPUT_KIND_POINTS_F32);
  points.set_point_dims(3);
  EXPECT_THAT(std::string(PlanWireJob(points).status().message()), HasSubstr("only for meshes"));
}

TEST(PolygonJobTest, BadCountsAreRefusedNamingThePolygon) {
  std::vector<uint32_t> counts(96, 2);
  counts[7] = 0;
  JobRun run = RunOne(PolygonSpec(v1::ALGORITHM_ML, 0, counts));
  ASSERT_FALSE(run.result.ok());
  EXPECT_EQ(run.result.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(run.result.status().message()),
              HasSubstr("spec.polygon_triangle_counts: polygons: polygon 7 has 0 triangles"));
  counts.assign(95, 2);
  run = RunOne(PolygonSpec(v1::ALGORITHM_ML, 0, counts));
  EXPECT_THAT(std::string(run.result.status().message()),
              HasSubstr("add up to 190, not the mesh's 192 faces"));
  run = RunOne(PolygonSpec(v1::ALGORITHM_EMLO, 97, std::vector<uint32_t>(96, 2)));
  EXPECT_THAT(std::string(run.result.status().message()), HasSubstr("96 polygons"));
}

// The levels as the client reads them: the snapshot, then each level's triplets.
TEST(PolygonJobTest, NoLevelSplitsAPolygon) {
  const std::vector<uint32_t> squares(96, 2);
  for (v1::Algorithm algorithm : {v1::ALGORITHM_ML, v1::ALGORITHM_EMLO, v1::ALGORITHM_BB}) {
    JobRun run = RunOne(PolygonSpec(algorithm, 6, squares));
    ASSERT_TRUE(run.result.ok()) << run.result.status();
    std::vector<uint32_t> labels;
    int levels = 0;
    for (const v1::JobEvent& event : run.events) {
      if (event.has_snapshot()) {
        labels.assign(event.snapshot().labels().begin(), event.snapshot().labels().end());
        for (size_t p = 0; p < 96; ++p) ASSERT_EQ(labels[2 * p], labels[2 * p + 1]);
      }
      if (!event.has_levels()) continue;
      const v1::LevelBatch& batch = event.levels();
      ASSERT_FALSE(batch.last_level_continues());
      int at = 0;
      for (int l = 0; l < batch.triplet_end_size(); ++l) {
        for (; at < static_cast<int>(batch.triplet_end(l)); ++at) {
          labels[batch.element(at)] = batch.to_cluster(at);
        }
        ++levels;
        for (size_t p = 0; p < 96; ++p) {
          ASSERT_EQ(labels[2 * p], labels[2 * p + 1]) << "square " << p << " level " << levels;
        }
      }
    }
    EXPECT_GT(levels, 0);
    ASSERT_EQ(labels.size(), 192u);
  }
}

}  // namespace
}  // namespace mlclust::server
