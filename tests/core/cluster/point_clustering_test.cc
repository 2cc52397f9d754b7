#include "core/cluster/point_clustering.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <limits>
#include <map>
#include <set>

#include "absl/container/flat_hash_set.h"
#include "core/base/random.h"
#include "core/hierarchy/model_selection.h"
#include "tbb/global_control.h"
#include "tests/fixtures/level_checks.h"
#include "tests/fixtures/recording_sink.h"
#include "tests/fixtures/test_points.h"

namespace mlclust {
namespace {

// `k` Gaussian blobs of `per` points with sigma 1 in d dimensions, centres uniform in
// [-25, 25]^d at least `separation` apart. Returns the points and the true labels.
std::pair<PointSet, std::vector<ClusterId>> Blobs(uint32_t k, uint32_t per, uint32_t d,
                                                  uint64_t seed, double separation = 10) {
  Random random(seed);
  std::vector<std::vector<double>> centres;
  while (centres.size() < k) {
    std::vector<double> c(d);
    for (double& v : c) v = -25 + 50 * random.Unit();
    bool far = true;
    for (const auto& o : centres) {
      double dist = 0;
      for (uint32_t j = 0; j < d; ++j) dist += (c[j] - o[j]) * (c[j] - o[j]);
      far = far && dist > separation * separation;
    }
    if (far) centres.push_back(c);
  }
  PointSet points;
  points.dims = d;
  std::vector<ClusterId> truth;
  for (uint32_t c = 0; c < k; ++c) {
    for (uint32_t i = 0; i < per; ++i) {
      for (uint32_t j = 0; j < d; ++j) {
        // Box-Muller.
        const double u = std::max(random.Unit(), 1e-300), v = random.Unit();
        points.values.push_back(static_cast<float>(
            centres[c][j] + std::sqrt(-2 * std::log(u)) * std::cos(6.283185307179586 * v)));
      }
      truth.push_back(ClusterId(c));
    }
  }
  return {points, truth};
}

using testing::SamePartition;

TEST(SubspaceIndexTest, HandMadeCasesIn2DAnd3D) {
  const std::vector<double> o2 = {0, 0};
  EXPECT_EQ(SubspaceIndex(o2, std::vector<double>{3, 1}), 0u);   // +x dominates
  EXPECT_EQ(SubspaceIndex(o2, std::vector<double>{-3, 1}), 1u);  // -x
  EXPECT_EQ(SubspaceIndex(o2, std::vector<double>{1, 3}), 2u);   // +y
  EXPECT_EQ(SubspaceIndex(o2, std::vector<double>{1, -3}), 3u);  // -y
  EXPECT_EQ(SubspaceIndex(o2, std::vector<double>{2, 2}), 0u);   // tie: the lower axis
  const std::vector<double> o3 = {1, 1, 1};
  EXPECT_EQ(SubspaceIndex(o3, std::vector<double>{1, 1, 5}), 4u);    // +z
  EXPECT_EQ(SubspaceIndex(o3, std::vector<double>{1, 1, -5}), 5u);   // -z
  EXPECT_EQ(SubspaceIndex(o3, std::vector<double>{0.5, 4, 2}), 2u);  // +y
  // Seen from the other side the subspace flips sign.
  EXPECT_EQ(SubspaceIndex(std::vector<double>{1, 1, 5}, o3), 5u);
}

TEST(VoxelGridStartTest, OnlyOccupiedCellsBecomeClusters) {
  PointSet points;
  points.dims = 2;
  // A 4 x 4 grid over [0, 4]^2: points in cells (0,0) x2, (3,3), (0,3); the rest empty.
  points.values = {0.1f, 0.1f, 0.2f, 0.3f, 3.9f, 3.9f, 0.5f, 3.5f, 4.0f, 4.0f, 0.0f, 0.0f};
  absl::StatusOr<VoxelStart> start = VoxelGridStart(points, 4);
  ASSERT_TRUE(start.ok()) << start.status();
  EXPECT_EQ(start->clusters, 3u);
  EXPECT_EQ(start->labels[0], start->labels[1]);
  EXPECT_EQ(start->labels[2], start->labels[4]);  // 4.0 falls in the last cell
  EXPECT_EQ(start->labels[0], start->labels[5]);
  EXPECT_NE(start->labels[0], start->labels[3]);
  // 16 dimensions with a = 10 would be 10^16 cells: only the occupied ones exist.
  auto [blobs, truth] = Blobs(4, 50, 16, 3);
  absl::StatusOr<VoxelStart> high = VoxelGridStart(blobs, 10);
  ASSERT_TRUE(high.ok());
  EXPECT_LE(high->clusters, blobs.num_points());
  EXPECT_EQ(VoxelGridStart(points, (1u << 20) + 1).status().code(),
            absl::StatusCode::kInvalidArgument);
  // grid 0: the default, about eight points per occupied cell (here 6 points: one cell).
  absl::StatusOr<VoxelStart> chosen = VoxelGridStart(points, 0);
  ASSERT_TRUE(chosen.ok());
  EXPECT_EQ(chosen->clusters, 1u);
}

// The voxel start's cells, numbered in order of their first point: packed into 64-bit keys
// and found in parallel blocks where the coordinates fit (3-D, 90,000 points: two blocks
// of 65,536), cell vectors otherwise (4-D at 2^17 cells per axis: 68 bits); both against
// the cells computed here point after point.
TEST(VoxelGridStartTest, CellsNumberedByTheirFirstPointPackedOrNot) {
  for (const auto& [dims, grid] : {std::pair<uint32_t, uint32_t>{3, 37}, {4, 1u << 17}}) {
    SCOPED_TRACE(dims);
    auto [points, truth] = Blobs(3, dims == 3 ? 30000 : 3000, dims, 43, 6);
    const size_t m = points.num_points();
    std::vector<float> lo(dims, std::numeric_limits<float>::max());
    std::vector<float> hi(dims, -std::numeric_limits<float>::max());
    for (size_t i = 0; i < m; ++i) {
      for (uint32_t j = 0; j < dims; ++j) {
        lo[j] = std::min(lo[j], points.values[i * dims + j]);
        hi[j] = std::max(hi[j], points.values[i * dims + j]);
      }
    }
    std::map<std::vector<uint32_t>, uint32_t> first;
    std::vector<uint32_t> expected(m);
    for (size_t i = 0; i < m; ++i) {
      std::vector<uint32_t> cell(dims);
      for (uint32_t j = 0; j < dims; ++j) {
        const double span = static_cast<double>(hi[j]) - lo[j];
        const double t = (points.values[i * dims + j] - lo[j]) / span;
        cell[j] = static_cast<uint32_t>(std::min<double>(grid - 1, t * grid));
      }
      expected[i] = first.try_emplace(cell, static_cast<uint32_t>(first.size())).first->second;
    }
    absl::StatusOr<VoxelStart> start = VoxelGridStart(points, grid);
    ASSERT_TRUE(start.ok()) << start.status();
    EXPECT_EQ(start->clusters, first.size());
    EXPECT_GT(first.size(), 100u);
    ASSERT_EQ(start->labels.size(), m);
    size_t differ = 0;
    for (size_t i = 0; i < m; ++i) differ += start->labels[i].value() != expected[i] ? 1 : 0;
    EXPECT_EQ(differ, 0u);
  }
}

// A level that moves over 16,384 points (the last merges of two blobs of 20,000) squashes
// its moves in parallel blocks joined in order: the same levels on one, two and three
// threads, and the triplets rebuild every level's labels as inspect_level reports them
// (the recorder's blocks against its in-order loop: level_recorder_parallel_test).
TEST(PointMultilevelTest, LargeLevelsSquashInBlocksTheSameOnOneTwoAndThreeThreads) {
  // TBB limits its workers to the machine's cores less one (one worker on 2 cores, where
  // three threads would run as two): allow four, so that three threads really run.
  tbb::global_control allow(tbb::global_control::max_allowed_parallelism, 4);
  auto [points, truth] = Blobs(2, 20000, 3, 47, 20);
  PointMultilevelOptions options;
  options.grid = 3;
  std::vector<std::vector<uint32_t>> inspected;
  std::vector<testing::RecordingSink> sinks(3);
  for (int threads = 1; threads <= 3; ++threads) {
    options.threads = threads;
    if (threads == 1) {
      options.inspect_level = [&](size_t /*level*/, std::span<const uint32_t> labels) {
        inspected.emplace_back(labels.begin(), labels.end());
      };
    } else {
      options.inspect_level = nullptr;
    }
    ASSERT_TRUE(RunPointMultilevel(points, options, sinks[threads - 1]).ok());
  }
  testing::ExpectSameLevels(sinks[0], sinks[1], /*with_start=*/true);
  testing::ExpectSameLevels(sinks[0], sinks[2], /*with_start=*/true);
  const testing::RecordingSink& sink = sinks[0];
  ASSERT_EQ(inspected.size(), sink.counts.size());
  std::vector<uint32_t> labels = sink.start;
  EXPECT_EQ(labels, inspected[0]);
  uint32_t largest = 0;
  size_t at = 0;
  for (size_t level = 1; level < sink.counts.size(); ++level) {
    const uint32_t count = sink.moves[at++];
    largest = std::max(largest, count);
    for (uint32_t t = 0; t < count; ++t, at += 3) {
      ASSERT_EQ(labels[sink.moves[at]], sink.moves[at + 2]);
      labels[sink.moves[at]] = sink.moves[at + 1];
    }
    ASSERT_EQ(labels, inspected[level]) << level;
  }
  EXPECT_GE(largest, 16384u);
}

TEST(LnKmeansTest, FromTheVoxelGridKeepsOneClusterPerOccupiedCellAndLowersTheEnergy) {
  auto [points, truth] = Blobs(5, 300, 3, 31, 8);
  absl::StatusOr<VoxelStart> start = VoxelGridStart(points, 6);
  ASSERT_TRUE(start.ok());
  absl::StatusOr<LnKmeansResult> result = RunLnKmeansFromGrid(points, 6);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_TRUE(result->converged);
  EXPECT_NEAR(result->initial_energy, PointEnergy(points, start->labels),
              1e-9 * result->initial_energy);
  EXPECT_NEAR(result->energy, PointEnergy(points, result->labels), 1e-9 * result->energy);
  EXPECT_LT(result->energy, result->initial_energy);
  std::set<uint32_t> distinct;
  for (ClusterId c : result->labels) distinct.insert(c.value());
  EXPECT_EQ(distinct.size(), start->clusters);
}

// A plain Lloyd from the same start, for comparison.
std::vector<ClusterId> Lloyd(const PointSet& points, std::vector<ClusterId> labels, uint32_t k) {
  const uint32_t d = points.dims;
  for (int iteration = 0; iteration < 100; ++iteration) {
    std::vector<double> sum(k * d, 0.0);
    std::vector<double> count(k, 0.0);
    for (size_t i = 0; i < labels.size(); ++i) {
      count[labels[i].value()] += 1;
      for (uint32_t j = 0; j < d; ++j) sum[labels[i].value() * d + j] += points.values[i * d + j];
    }
    bool moved = false;
    for (size_t i = 0; i < labels.size(); ++i) {
      double best = 1e300;
      uint32_t best_c = labels[i].value();
      for (uint32_t c = 0; c < k; ++c) {
        if (count[c] == 0) continue;
        double dist = 0;
        for (uint32_t j = 0; j < d; ++j) {
          const double diff = points.values[i * d + j] - sum[c * d + j] / count[c];
          dist += diff * diff;
        }
        if (dist < best) {
          best = dist;
          best_c = c;
        }
      }
      moved = moved || best_c != labels[i].value();
      labels[i] = ClusterId(best_c);
    }
    if (!moved) break;
  }
  return labels;
}

TEST(LnKmeansTest, ReachesLloydsPartitionOnSeparatedDataAndNeverRaisesTheEnergy) {
  for (uint32_t d : {2u, 3u, 8u}) {
    auto [points, truth] = Blobs(12, 200, d, d);
    absl::StatusOr<std::vector<ClusterId>> start = SeedPointClusters(points, 12, true, 5);
    ASSERT_TRUE(start.ok());
    std::vector<double> energies;
    LnKmeansOptions options;
    options.on_iteration = [&](uint32_t, uint64_t, double e) { energies.push_back(e); };
    absl::StatusOr<LnKmeansResult> result = RunLnKmeans(points, *start, options);
    ASSERT_TRUE(result.ok()) << result.status();
    EXPECT_TRUE(result->converged);
    double previous = result->initial_energy;
    for (double e : energies) {
      EXPECT_LE(e, previous * (1 + 1e-12));
      previous = e;
    }
    EXPECT_TRUE(SamePartition(result->labels, Lloyd(points, *start, 12))) << "d=" << d;
    EXPECT_NEAR(result->energy, PointEnergy(points, result->labels), 1e-6 * result->energy);
  }
}

// Over 65,536 points the points to check in the next iteration are collected in parallel
// slices: one thread and two give the same iterations, moves and labels.
TEST(LnKmeansTest, IterationsDoNotDependOnTheThreadCount) {
  auto [points, truth] = Blobs(50, 1600, 3, 37, 3);
  LnKmeansOptions options;
  std::vector<uint64_t> moved_one, moved_two;
  options.threads = 1;
  options.on_iteration = [&](uint32_t, uint64_t moved, double) { moved_one.push_back(moved); };
  absl::StatusOr<LnKmeansResult> one = RunLnKmeansFromGrid(points, 20, options);
  options.threads = 2;
  options.on_iteration = [&](uint32_t, uint64_t moved, double) { moved_two.push_back(moved); };
  absl::StatusOr<LnKmeansResult> two = RunLnKmeansFromGrid(points, 20, options);
  ASSERT_TRUE(one.ok() && two.ok());
  EXPECT_GT(one->iterations, 2u);
  EXPECT_EQ(moved_one, moved_two);
  EXPECT_EQ(one->labels, two->labels);
  EXPECT_EQ(one->energy, two->energy);
}

TEST(LnKmeansTest, BadInputIsRefused) {
  PointSet points;
  points.dims = 2;
  points.values = {0, 0, 1, std::numeric_limits<float>::quiet_NaN()};
  EXPECT_EQ(RunLnKmeans(points, {ClusterId(0), ClusterId(0)}).status().code(),
            absl::StatusCode::kInvalidArgument);
  points.values = {0, 0, 1, 1};
  EXPECT_EQ(RunLnKmeans(points, {ClusterId(0)}).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(SeedPointClusters(points, 3, true, 1).status().code(),
            absl::StatusCode::kInvalidArgument);
}

using testing::EnergyByCount;

TEST(PointMultilevelTest, RebuildsTheEnginesLabelsAndReportsTheirEnergy) {
  auto [points, truth] = Blobs(8, 300, 3, 11);
  testing::EngineLabels engine([](size_t level) { return level % 97 == 3; });
  PointMultilevelOptions options;
  options.grid = 12;
  options.inspect_level = engine.Inspector();
  HierarchyLog log;
  absl::StatusOr<PointMultilevelSummary> summary = RunPointMultilevel(points, options, log);
  ASSERT_TRUE(summary.ok()) << summary.status();
  EXPECT_EQ(summary->final_clusters, 1u);
  EXPECT_EQ(log.cluster_count(0), summary->start_clusters);
  ASSERT_FALSE(engine.levels.empty());
  for (const auto& [level, labels] : engine.levels) {
    ASSERT_EQ(*log.LabelsAt(level), labels) << level;
    const double direct = PointEnergy(points, labels);
    EXPECT_NEAR(log.energy(level), direct, 1e-6 * direct + 1e-9) << level;
  }
  // The 8 blobs are recovered exactly at 8 clusters.
  const std::optional<size_t> eight = log.LastLevelWith(8);
  ASSERT_TRUE(eight.has_value());
  EXPECT_TRUE(SamePartition(*log.LabelsAt(*eight), truth));
}

// Issue 26 item 3: the text's start (Fig. 6.5 / 6.8), LN k-means on the voxel clusters before
// the first level: level 0 is RunLnKmeansFromGrid's partition with its energy, below the raw
// grid's; the default start is the raw grid (VoxelGridStart), and both hierarchies end at 1.
TEST(PointMultilevelTest, TheOptimisedGridStartsFromLnKmeansOnTheVoxels) {
  auto [points, truth] = Blobs(8, 300, 3, 11);
  PointMultilevelOptions options;
  options.grid = 12;
  HierarchyLog raw, optimised;
  ASSERT_TRUE(RunPointMultilevel(points, options, raw).ok());
  options.start = PointMultilevelOptions::Start::kOptimisedGrid;
  ASSERT_TRUE(RunPointMultilevel(points, options, optimised).ok());
  const absl::StatusOr<VoxelStart> grid = VoxelGridStart(points, 12);
  ASSERT_TRUE(grid.ok());
  EXPECT_TRUE(SamePartition(*raw.LabelsAt(0), grid->labels));
  LnKmeansOptions ln;
  const absl::StatusOr<LnKmeansResult> ln_kmeans = RunLnKmeansFromGrid(points, 12, ln);
  ASSERT_TRUE(ln_kmeans.ok());
  const std::vector<ClusterId> start = *optimised.LabelsAt(0);
  EXPECT_TRUE(SamePartition(start, ln_kmeans->labels));
  std::set<uint32_t> used;
  for (ClusterId c : ln_kmeans->labels) used.insert(c.value());
  EXPECT_EQ(optimised.cluster_count(0), used.size());
  EXPECT_NEAR(optimised.energy(0), ln_kmeans->energy, 1e-9 * ln_kmeans->energy);
  EXPECT_NEAR(optimised.energy(0), PointEnergy(points, start), 1e-9 * optimised.energy(0));
  EXPECT_LT(optimised.energy(0), raw.energy(0));
  EXPECT_EQ(optimised.cluster_count(optimised.num_levels() - 1), 1u);
  const std::optional<size_t> eight = optimised.LastLevelWith(8);
  ASSERT_TRUE(eight.has_value());
  EXPECT_TRUE(SamePartition(*optimised.LabelsAt(*eight), truth));
}

TEST(PointMultilevelTest, MlIsAtMostHcAtNearlyEveryLevel) {
  auto [points, truth] = Blobs(6, 400, 3, 21, 6);
  PointMultilevelOptions ml_options, hc_options;
  ml_options.grid = hc_options.grid = 16;
  hc_options.optimizer = PointMultilevelOptions::Optimizer::kNone;
  HierarchyLog ml, hc;
  ASSERT_TRUE(RunPointMultilevel(points, ml_options, ml).ok());
  ASSERT_TRUE(RunPointMultilevel(points, hc_options, hc).ok());
  const auto ml_energy = EnergyByCount(ml), hc_energy = EnergyByCount(hc);
  size_t worse = 0;
  for (const auto& [k, e] : ml_energy) worse += e > hc_energy.at(k) * (1 + 1e-9);
  EXPECT_LE(worse, ml_energy.size() / 100);
  for (uint32_t k : {6u, 20u, 100u}) {
    EXPECT_LE(ml_energy.at(k), hc_energy.at(k) * (1 + 1e-9)) << k;
  }
}

TEST(PointMultilevelTest, PmlReachesOneClusterAndFarApartGroupsStillMerge) {
  // Two blobs 1000 apart: their voxels never touch, yet the hierarchy ends at one cluster.
  auto [points, truth] = Blobs(2, 100, 3, 5);
  for (size_t i = 0; i < 100 * 3; i += 3) points.values[i] += 1000;
  PointMultilevelOptions options;
  options.parallel = true;
  HierarchyLog log;
  absl::StatusOr<PointMultilevelSummary> summary = RunPointMultilevel(points, options, log);
  ASSERT_TRUE(summary.ok());
  EXPECT_EQ(summary->final_clusters, 1u);
  EXPECT_TRUE(SamePartition(*log.LabelsAt(*log.FirstLevelWithAtMost(2)), truth));
}

TEST(PointMultilevelTest, PmlStaysCloseToMlAtEveryLevel) {
  // Blobs of unequal spacing: near the blobs' own scale the mutual pairs of a PML level mix
  // pieces of one blob with whole blobs. Collapsing only the cheaper half keeps PML's
  // energy near ML's at every level PML produces, in far fewer levels.
  auto [points, truth] = Blobs(40, 250, 3, 17, 3);
  PointMultilevelOptions ml_options, pml_options;
  pml_options.parallel = true;
  HierarchyLog ml, pml;
  ASSERT_TRUE(RunPointMultilevel(points, ml_options, ml).ok());
  ASSERT_TRUE(RunPointMultilevel(points, pml_options, pml).ok());
  const auto ml_energy = EnergyByCount(ml);
  EXPECT_LT(pml.num_levels() * 4, ml.num_levels());
  for (size_t l = 0; l < pml.num_levels(); ++l) {
    const uint32_t k = pml.cluster_count(l);
    EXPECT_LE(pml.energy(l), 1.25 * ml_energy.at(k)) << k << " clusters";
  }
}

using testing::RecordingSink;

// RunPointMultilevel on `points`, as ExpectSameLevelsOnOneAndTwoThreads calls it.
auto RunPoints(const PointSet& points) {
  return [&points](const PointMultilevelOptions& options, LevelSink& sink) {
    return RunPointMultilevel(points, options, sink);
  };
}

// The engine's parallel steps (ODEs, mutual pairs, the ODE refresh of a level, LN
// k-means' assignment) give the same levels on one thread as on two: PML, PML then ML,
// and ML.
TEST(PointMultilevelTest, LevelsDoNotDependOnTheThreadCount) {
  auto [points, truth] = Blobs(60, 200, 3, 23, 4);
  for (int variant = 0; variant < 3; ++variant) {
    SCOPED_TRACE(variant);
    PointMultilevelOptions options;
    options.parallel = variant < 2;
    options.pml_until = variant == 1 ? 200 : 0;
    testing::ExpectSameLevelsOnOneAndTwoThreads(options, RunPoints(points), 5,
                                                /*with_start=*/true);
  }
}

// Large enough that the upper levels' LN k-means rounds scan and check the changed
// clusters in up to 64 tasks of thousands of points (Optimise's ScanAndCheck): the same
// levels on one thread as on two.
TEST(PointMultilevelTest, ParallelRoundScansDoNotDependOnTheThreadCount) {
  auto [points, truth] = Blobs(40, 1000, 3, 29, 4);
  testing::ExpectSameLevelsOnOneAndTwoThreads(PointMultilevelOptions(), RunPoints(points), 100);
}

// Optimise's rounds scan and check in tasks of about 512 members, in parallel where a round
// has more than one (here the upper levels' clusters hold thousands of points), joined in
// order: the same levels on one, two and three threads, for ML, ML with bounded_drift
// (ours) and PML then ML.
TEST(PointMultilevelTest, RoundTasksGiveTheSameLevelsOnOneTwoAndThreeThreads) {
  auto [points, truth] = Blobs(12, 500, 3, 37, 4);
  for (int variant = 0; variant < 3; ++variant) {
    SCOPED_TRACE(variant);
    PointMultilevelOptions options;
    options.grid = 24;  // many small start cells: several hundred ML levels
    if (variant == 1) options.bounded_drift = 0.1;
    if (variant == 2) {
      options.parallel = true;
      options.pml_until = 100;
    }
    std::vector<testing::RecordingSink> sinks(3);
    for (int threads = 1; threads <= 3; ++threads) {
      options.threads = threads;
      ASSERT_TRUE(RunPointMultilevel(points, options, sinks[threads - 1]).ok());
    }
    EXPECT_GT(sinks[0].counts.size(), variant == 2 ? 50u : 300u);
    EXPECT_EQ(sinks[0].counts.back(), 1u);
    testing::ExpectSameLevels(sinks[0], sinks[1], /*with_start=*/true);
    testing::ExpectSameLevels(sinks[0], sinks[2], /*with_start=*/true);
  }
}

// optimise_rounds (ours): 8 is the default's hierarchy exactly; fewer rounds still make one
// merge per level and change the hierarchy, at a higher energy where the clusters are large
// (measured in BENCHMARKS.md: here about +6% on average, at most +23%); 0 and 65 are
// refused.
TEST(PointMultilevelTest, OptimiseRoundsEightIsTheDefaultAndFewerStayNear) {
  auto [points, truth] = Blobs(30, 300, 3, 31, 4);
  PointMultilevelOptions options;
  RecordingSink by_default, eight, two;
  ASSERT_TRUE(RunPointMultilevel(points, options, by_default).ok());
  options.optimise_rounds = 8;
  ASSERT_TRUE(RunPointMultilevel(points, options, eight).ok());
  testing::ExpectSameLevels(by_default, eight);
  options.optimise_rounds = 2;
  ASSERT_TRUE(RunPointMultilevel(points, options, two).ok());
  ASSERT_EQ(two.counts, by_default.counts);
  EXPECT_NE(two.moves, by_default.moves);
  EXPECT_LT(testing::MeanEnergyRatio(two, by_default, 1.5, 100), 1.10);
  for (uint32_t bad : {0u, 65u}) {
    options.optimise_rounds = bad;
    RecordingSink sink;
    EXPECT_EQ(RunPointMultilevel(points, options, sink).status().code(),
              absl::StatusCode::kInvalidArgument)
        << bad;
  }
}

// bounded_drift (ours, off by default): the same number of levels, one merge each; where a
// changed cluster moved by less than the share of its radius its unchecked points stay
// unchecked, which changes some levels' moves at a higher energy. How much depends on the
// data: here (295 start cells of ~100 points, 0.1) about +8% on average and up to +37%
// near the start, whose cells no longer all get optimised; the blobs are found all the
// same (BENCHMARKS.md, "ML for points: bounded_drift", for 1,000 blobs). Out-of-range
// values refused.
TEST(PointMultilevelTest, BoundedDriftChangesLittleAndOffIsTheDefault) {
  auto [points, truth] = Blobs(20, 1500, 3, 41, 4);
  PointMultilevelOptions options;
  RecordingSink by_default, off, bounded;
  ASSERT_TRUE(RunPointMultilevel(points, options, by_default).ok());
  options.bounded_drift = 0;
  ASSERT_TRUE(RunPointMultilevel(points, options, off).ok());
  testing::ExpectSameLevels(by_default, off);
  options.bounded_drift = 0.1;
  ASSERT_TRUE(RunPointMultilevel(points, options, bounded).ok());
  ASSERT_EQ(bounded.counts, by_default.counts);
  EXPECT_EQ(bounded.start, by_default.start);
  EXPECT_NE(bounded.moves, by_default.moves);
  const double mean_ratio = testing::MeanEnergyRatio(bounded, by_default, 1.5, 200);
  EXPECT_LT(mean_ratio, 1.15) << mean_ratio;
  // The blobs are found all the same.
  const size_t twenty = bounded.counts.size() - 20;
  EXPECT_EQ(bounded.counts[twenty], 20u);
  EXPECT_NEAR(bounded.energies[twenty], by_default.energies[twenty],
              1e-3 * by_default.energies[twenty]);
  for (double bad : {-0.1, 1.5, std::nan("")}) {
    options.bounded_drift = bad;
    RecordingSink sink;
    EXPECT_EQ(RunPointMultilevel(points, options, sink).status().code(),
              absl::StatusCode::kInvalidArgument)
        << bad;
  }
}

TEST(PointMultilevelTest, AnIsolatedOutlierCellStillMergesWhereItIsCheapest) {
  // Two dense groups joined by a bridge of points (so their cells touch face to face) and
  // one outlier whose cell touches no occupied cell. Once the groups have merged into
  // each other's neighbourhood, the outlier must join the nearer group at 2 clusters: a
  // cluster with no neighbours at all would otherwise never be offered a merge, and the
  // groups would merge with each other at a far higher cost first.
  PointSet points;
  points.dims = 3;
  Random random(3);
  auto add = [&](double x, double y, double z) {
    points.values.insert(points.values.end(),
                         {static_cast<float>(x), static_cast<float>(y), static_cast<float>(z)});
  };
  for (int i = 0; i < 200; ++i) add(0.5 * random.Unit(), 0.5 * random.Unit(), 0.5 * random.Unit());
  for (int i = 0; i < 200; ++i) {
    add(9.5 + 0.5 * random.Unit(), 0.5 * random.Unit(), 0.5 * random.Unit());
  }
  for (double x = 0.5; x < 9.5; x += 0.25) add(x, 0.25, 0.25);
  const size_t outlier = points.num_points();
  add(0.25, 4.0, 0.25);
  add(10.0, 10.0, 10.0);  // stretches the box so the grid below has cells of size 1
  PointMultilevelOptions options;
  options.grid = 10;
  HierarchyLog log;
  ASSERT_TRUE(RunPointMultilevel(points, options, log).ok());
  const std::optional<size_t> two = log.LastLevelWith(3);
  ASSERT_TRUE(two.has_value());
  const std::vector<ClusterId> labels = *log.LabelsAt(*two);
  size_t with_outlier = 0;
  for (size_t i = 0; i < labels.size(); ++i) with_outlier += labels[i] == labels[outlier];
  EXPECT_GT(with_outlier, 1u) << "the outlier is still alone at 3 clusters";
  // And the energy never drops by more than rounding from one level to the next coarser.
  for (size_t l = 1; l < log.num_levels(); ++l) {
    EXPECT_GE(log.energy(l), log.energy(l - 1) * (1 - 1e-9) - 1e-9) << l;
  }
}

TEST(PointMultilevelTest, HighDimensionalDataStartsFromManyCellsAndFindsTheBlobs) {
  // At d = 64 no uniform grid fits eight points a cell (2^64 cells); the default start
  // halves the widest cells axis by axis instead, and ML still separates the blobs.
  auto [points, truth] = Blobs(6, 300, 64, 7, 20);
  HierarchyLog log;
  absl::StatusOr<PointMultilevelSummary> summary = RunPointMultilevel(points, {}, log);
  ASSERT_TRUE(summary.ok()) << summary.status();
  EXPECT_GT(summary->start_clusters, 6u * 10);
  const std::optional<size_t> six = log.LastLevelWith(6);
  ASSERT_TRUE(six.has_value());
  EXPECT_TRUE(SamePartition(*log.LabelsAt(*six), truth));
}

}  // namespace
}  // namespace mlclust

namespace mlclust {
namespace {

// Section 6.6: the ML hierarchy's BIC recovers the number of well separated Gaussians.
TEST(PointMultilevelTest, BicOfTheMlHierarchyRecoversTheNumberOfBlobs) {
  for (uint32_t k : {5u, 12u, 30u}) {
    auto [points, truth] = Blobs(k, 200, 3, 100 + k, 8);
    BicLevelRecorder recorder;
    ASSERT_TRUE(RunPointMultilevel(points, {}, recorder).ok());
    absl::StatusOr<BicChoice> choice =
        ChooseByBic(recorder.levels(), recorder.num_points(), points.dims);
    ASSERT_TRUE(choice.ok()) << choice.status();
    EXPECT_EQ(choice->best_k, k);
  }
}

using testing::CancelAfter;

TEST(PointCancelTest, ASetFlagStopsEveryCallWithCancelled) {
  const auto [points, truth] = Blobs(6, 200, 3, 11);
  std::atomic<bool> cancel{true};
  EXPECT_EQ(VoxelGridStart(points, 0, &cancel).status().code(), absl::StatusCode::kCancelled);
  LnKmeansOptions ln;
  ln.cancel = &cancel;
  EXPECT_EQ(RunLnKmeansFromGrid(points, 0, ln).status().code(), absl::StatusCode::kCancelled);
  EXPECT_EQ(RunLnKmeans(points, truth, ln).status().code(), absl::StatusCode::kCancelled);
  PointMultilevelOptions ml;
  ml.cancel = &cancel;
  HierarchyLog log;
  EXPECT_EQ(RunPointMultilevel(points, ml, log).status().code(), absl::StatusCode::kCancelled);
  EXPECT_EQ(log.num_levels(), 0u);  // stopped before the start was reported
  cancel = false;
  EXPECT_TRUE(VoxelGridStart(points, 0, &cancel).ok());
  EXPECT_TRUE(RunLnKmeans(points, truth, ln).ok());
}

// A flag set while the run goes stops it at the next level (ML and PML) or the next stage
// of an LN k-means iteration.
TEST(PointCancelTest, AFlagSetDuringTheRunStopsItAtTheNextCheck) {
  const auto [points, truth] = Blobs(6, 200, 3, 12);
  for (bool parallel : {false, true}) {
    std::atomic<bool> cancel{false};
    PointMultilevelOptions options;
    options.parallel = parallel;
    options.cancel = &cancel;
    CancelAfter log(cancel, 5);
    const auto summary = RunPointMultilevel(points, options, log);
    EXPECT_EQ(summary.status().code(), absl::StatusCode::kCancelled) << parallel;
    EXPECT_EQ(log.num_levels(), 6u) << parallel;  // level 0 and the five before the flag
  }
  std::atomic<bool> cancel{false};
  LnKmeansOptions ln;
  ln.cancel = &cancel;
  uint32_t iterations = 0;
  ln.on_iteration = [&](uint32_t, uint64_t moved, double) {
    ++iterations;
    EXPECT_GT(moved, 0u);  // so the run would go on
    cancel = true;
  };
  std::vector<ClusterId> scrambled(points.num_points());
  for (size_t i = 0; i < scrambled.size(); ++i) scrambled[i] = ClusterId(i % 6);
  EXPECT_EQ(RunLnKmeans(points, scrambled, ln).status().code(), absl::StatusCode::kCancelled);
  EXPECT_EQ(iterations, 1u);
}

}  // namespace
}  // namespace mlclust
