#include "core/cluster/kmeans.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <numbers>

#include "core/base/random.h"
#include "tests/fixtures/test_points.h"

namespace mlclust {
namespace {

using ::testing::HasSubstr;

using testing::Blobs;

// Blobs whose rows are shuffled, so that blocks of rows mix clusters.
Blobs GaussianBlobs(uint32_t clusters, uint32_t per_cluster, double separation, uint64_t seed) {
  return testing::GaussianBlobs(clusters, per_cluster, separation, seed, /*shuffle=*/true);
}

PointSet UniformPoints(size_t m, uint32_t d, uint64_t seed) {
  Random random(seed);
  PointSet points;
  points.dims = d;
  points.values.resize(m * d);
  for (float& v : points.values) v = static_cast<float>(random.Unit() * 100);
  return points;
}

using testing::SamePartition;

// Both seedings, for the tests that hold for either.
constexpr KmeansOptions::Init kBothInits[] = {KmeansOptions::Init::kRandom,
                                              KmeansOptions::Init::kKmeansPlusPlus};

KmeansOptions Options(uint32_t clusters, KmeansOptions::Init init) {
  KmeansOptions options;
  options.clusters = clusters;
  options.init = init;
  return options;
}

// The energy of `labels` against their double-precision means, computed directly.
double DirectInertia(const PointSet& points, const std::vector<ClusterId>& labels, uint32_t k) {
  const uint32_t d = points.dims;
  std::vector<double> sums(size_t{k} * d, 0.0), counts(k, 0.0);
  for (size_t i = 0; i < labels.size(); ++i) {
    counts[labels[i].value()] += 1;
    for (uint32_t j = 0; j < d; ++j) sums[labels[i].value() * d + j] += points.point(i)[j];
  }
  double energy = 0;
  for (size_t i = 0; i < labels.size(); ++i) {
    const uint32_t c = labels[i].value();
    for (uint32_t j = 0; j < d; ++j) {
      const double t = points.point(i)[j] - sums[c * d + j] / counts[c];
      energy += t * t;
    }
  }
  return energy;
}

void ExpectValidResult(const PointSet& points, const KmeansResult& result, uint32_t k) {
  ASSERT_EQ(result.labels.size(), points.num_points());
  ASSERT_EQ(result.centres.size(), size_t{k} * points.dims);
  std::vector<size_t> sizes(k, 0);
  for (ClusterId label : result.labels) {
    ASSERT_LT(label.value(), k);
    ++sizes[label.value()];
  }
  for (uint32_t c = 0; c < k; ++c) EXPECT_GT(sizes[c], 0u) << "cluster " << c << " is empty";
  EXPECT_NEAR(result.inertia, DirectInertia(points, result.labels, k),
              1e-9 * std::max(1.0, result.inertia));
}

// k-means++ can put two seeds into one cluster, which Lloyd cannot undo; at K = 20 it does
// so in about one run in eight, as scikit-learn 1.2's KMeans(n_init=1) does on the same data
// (87 of 100 runs recover the partition for both). So: over 10 seeds, nearly all runs recover
// the generating partition, and every run that does not ends in a worse local minimum.
TEST(KmeansTest, RecoversWellSeparatedGaussians) {
  for (uint32_t clusters : {5u, 10u, 20u}) {
    const Blobs blobs = GaussianBlobs(clusters, 200, 8, /*seed=*/clusters);
    int recovered = 0;
    double best_recovered = std::numeric_limits<double>::infinity();
    double worst_recovered = 0;
    double best_missed = std::numeric_limits<double>::infinity();
    for (uint64_t seed = 1; seed <= 10; ++seed) {
      KmeansOptions options;
      options.clusters = clusters;
      options.seed = seed;
      absl::StatusOr<KmeansResult> result = RunKmeans(blobs.points, options);
      ASSERT_TRUE(result.ok()) << result.status();
      ExpectValidResult(blobs.points, *result, clusters);
      EXPECT_TRUE(result->converged);
      if (SamePartition(result->labels, blobs.truth)) {
        ++recovered;
        best_recovered = std::min(best_recovered, result->inertia);
        worst_recovered = std::max(worst_recovered, result->inertia);
      } else {
        best_missed = std::min(best_missed, result->inertia);
      }
    }
    std::printf("%u clusters: %d of 10 seeds recover the partition\n", clusters, recovered);
    EXPECT_GE(recovered, clusters == 5 ? 10 : 7) << clusters << " clusters";
    // The same partition gives the same energy whatever the seed.
    EXPECT_NEAR(best_recovered, worst_recovered, 1e-9 * worst_recovered);
    EXPECT_GT(best_missed, 1.2 * worst_recovered) << clusters << " clusters";
  }
}

TEST(KmeansTest, InertiaNeverIncreases) {
  const PointSet points = UniformPoints(20000, 3, 7);
  for (KmeansOptions::Init init : kBothInits) {
    KmeansOptions options = Options(40, init);
    options.tolerance = 0;
    std::vector<double> inertia;
    options.on_iteration = [&](uint32_t iteration, double value) {
      EXPECT_EQ(iteration, inertia.size() + 1);
      inertia.push_back(value);
    };
    absl::StatusOr<KmeansResult> result = RunKmeans(points, options);
    ASSERT_TRUE(result.ok()) << result.status();
    ExpectValidResult(points, *result, 40);
    ASSERT_EQ(inertia.size(), result->iterations);
    EXPECT_GT(result->iterations, 5u);
    for (size_t i = 1; i < inertia.size(); ++i) {
      EXPECT_LE(inertia[i], inertia[i - 1] * (1 + 1e-12)) << "iteration " << i + 1;
    }
    EXPECT_EQ(result->inertia, inertia.back());
    // Converged at a fixed point: every label is the nearest centre (in double, up to float
    // near-ties), and the centres are the means.
    EXPECT_TRUE(result->converged);
    for (size_t i = 0; i < points.num_points(); ++i) {
      double best = std::numeric_limits<double>::infinity();
      double own = 0;
      for (uint32_t c = 0; c < 40; ++c) {
        double s = 0;
        for (uint32_t j = 0; j < 3; ++j) {
          const double t = points.point(i)[j] - result->centres[c * 3 + j];
          s += t * t;
        }
        best = std::min(best, s);
        if (c == result->labels[i].value()) own = s;
      }
      ASSERT_LE(own, best * (1 + 1e-5) + 1e-6) << "point " << i;
    }
  }
}

TEST(KmeansTest, ThreadCountDoesNotChangeTheResult) {
  // Several blocks of points per chunk and several chunks.
  const PointSet points = UniformPoints(150000, 3, 3);
  KmeansOptions options;
  options.clusters = 64;
  options.max_iterations = 20;
  std::vector<KmeansResult> results;
  for (int threads : {1, 2}) {
    options.threads = threads;
    absl::StatusOr<KmeansResult> result = RunKmeans(points, options);
    ASSERT_TRUE(result.ok()) << result.status();
    results.push_back(*std::move(result));
  }
  for (size_t r = 1; r < results.size(); ++r) {
    EXPECT_EQ(results[r].labels, results[0].labels);
    EXPECT_EQ(results[r].centres, results[0].centres);
    EXPECT_EQ(results[r].inertia, results[0].inertia);  // bit for bit
    EXPECT_EQ(results[r].iterations, results[0].iterations);
  }
}

TEST(KmeansTest, SameSeedSameResultOtherSeedOtherSeeds) {
  const PointSet points = UniformPoints(5000, 2, 11);
  for (KmeansOptions::Init init : kBothInits) {
    KmeansOptions options = Options(12, init);
    options.max_iterations = 3;
    const KmeansResult a = *RunKmeans(points, options);
    const KmeansResult b = *RunKmeans(points, options);
    EXPECT_EQ(a.labels, b.labels);
    EXPECT_EQ(a.centres, b.centres);
    options.seed = 2;
    const KmeansResult c = *RunKmeans(points, options);
    EXPECT_NE(a.centres, c.centres);
  }
}

TEST(KmeansTest, PlusPlusCentresArePointsAndIndependentOfThreads) {
  const PointSet points = UniformPoints(30000, 5, 5);
  absl::StatusOr<std::vector<float>> one = KmeansPlusPlusCentres(points, 50, 9, 1);
  absl::StatusOr<std::vector<float>> two = KmeansPlusPlusCentres(points, 50, 9, 2);
  ASSERT_TRUE(one.ok()) << one.status();
  ASSERT_TRUE(two.ok()) << two.status();
  EXPECT_EQ(*one, *two);
  ASSERT_EQ(one->size(), 50u * 5);
  std::map<std::vector<float>, int> rows;
  for (size_t i = 0; i < points.num_points(); ++i) {
    rows[std::vector<float>(points.point(i).begin(), points.point(i).end())] = 0;
  }
  for (size_t c = 0; c < 50; ++c) {
    std::vector<float> centre(one->begin() + c * 5, one->begin() + (c + 1) * 5);
    auto it = rows.find(centre);
    ASSERT_NE(it, rows.end()) << "centre " << c << " is not a point";
    EXPECT_EQ(it->second++, 0) << "centre " << c << " repeats a centre";
  }
}

TEST(KmeansTest, PlusPlusSpreadsSeedsOverSeparatedClusters) {
  // One seed per cluster: greedy k-means++ rarely puts two in one of 10 far-apart blobs.
  const Blobs blobs = GaussianBlobs(10, 100, 15, 4);
  const std::vector<float> centres = *KmeansPlusPlusCentres(blobs.points, 10, 1, 0);
  std::vector<int> seeds_in(10, 0);
  for (size_t c = 0; c < 10; ++c) {
    for (size_t i = 0; i < blobs.points.num_points(); ++i) {
      if (std::equal(centres.begin() + c * 3, centres.begin() + c * 3 + 3,
                     blobs.points.point(i).begin())) {
        ++seeds_in[blobs.truth[i]];
        break;
      }
    }
  }
  EXPECT_THAT(seeds_in, ::testing::Each(1));
}

TEST(KmeansTest, LloydFromGivenCentresExact) {
  PointSet points{1, {0, 1, 10, 11}};
  std::vector<double> seen;
  KmeansOptions options;
  options.on_iteration = [&](uint32_t, double inertia) { seen.push_back(inertia); };
  absl::StatusOr<KmeansResult> result = RunLloyd(points, {0, 10}, options);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_THAT(result->labels,
              ::testing::ElementsAre(ClusterId(0), ClusterId(0), ClusterId(1), ClusterId(1)));
  EXPECT_THAT(result->centres, ::testing::ElementsAre(0.5f, 10.5f));
  EXPECT_EQ(result->inertia, 1.0);
  EXPECT_EQ(result->iterations, 2u);  // the second moves neither points nor centres
  EXPECT_TRUE(result->converged);
  EXPECT_THAT(seen, ::testing::ElementsAre(1.0, 1.0));
  EXPECT_EQ(result->seconds_init, 0.0);
}

// keep_first_assignment hands back, from the one run, the partition a separate run of
// max_iterations = 1 gives (labels and inertia bit for bit), including an empty cluster's
// refill; the run itself is not changed by it.
TEST(KmeansTest, FirstAssignmentKeptEqualsAOneIterationRun) {
  const Blobs blobs = GaussianBlobs(8, 400, 6, 21);
  for (KmeansOptions::Init init : kBothInits) {
    KmeansOptions options = Options(11, init);
    absl::StatusOr<KmeansResult> plain = RunKmeans(blobs.points, options);
    ASSERT_TRUE(plain.ok()) << plain.status();
    EXPECT_TRUE(plain->first_labels.empty());
    options.keep_first_assignment = true;
    absl::StatusOr<KmeansResult> kept = RunKmeans(blobs.points, options);
    ASSERT_TRUE(kept.ok()) << kept.status();
    options.keep_first_assignment = false;
    options.max_iterations = 1;
    absl::StatusOr<KmeansResult> one = RunKmeans(blobs.points, options);
    ASSERT_TRUE(one.ok()) << one.status();
    EXPECT_EQ(kept->first_labels, one->labels);
    EXPECT_EQ(kept->first_inertia, one->inertia);
    EXPECT_GT(kept->iterations, 1u);
    EXPECT_NE(kept->first_labels, kept->labels);  // later iterations moved points
    EXPECT_EQ(kept->labels, plain->labels);
    EXPECT_EQ(kept->inertia, plain->inertia);
  }
  // From given centres, with centre 100 attracting no point: the first partition is the
  // one after the refill.
  PointSet points{1, {0, 1, 2, 10}};
  KmeansOptions options;
  options.keep_first_assignment = true;
  absl::StatusOr<KmeansResult> result = RunLloyd(points, {0, 10, 100}, options);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_THAT(result->first_labels,
              ::testing::ElementsAre(ClusterId(0), ClusterId(0), ClusterId(2), ClusterId(1)));
  EXPECT_EQ(result->first_inertia, 0.5);
}

TEST(KmeansTest, EmptyClusterTakesTheFarthestPoint) {
  // Centre 100 attracts no point; the point farthest from its centre (2, at distance 2 from
  // centre 0) moves to it.
  PointSet points{1, {0, 1, 2, 10}};
  absl::StatusOr<KmeansResult> result = RunLloyd(points, {0, 10, 100}, {});
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_THAT(result->labels,
              ::testing::ElementsAre(ClusterId(0), ClusterId(0), ClusterId(2), ClusterId(1)));
  EXPECT_THAT(result->centres, ::testing::ElementsAre(0.5f, 10.0f, 2.0f));
  EXPECT_EQ(result->inertia, 0.5);
  EXPECT_TRUE(result->converged);
}

TEST(KmeansTest, DuplicatePointsKeepEveryClusterNonEmpty) {
  PointSet points{2, {}};
  for (int i = 0; i < 300; ++i) points.values.insert(points.values.end(), {1.5f, -2.0f});
  for (KmeansOptions::Init init : kBothInits) {
    KmeansOptions options = Options(7, init);
    absl::StatusOr<KmeansResult> result = RunKmeans(points, options);
    ASSERT_TRUE(result.ok()) << result.status();
    ExpectValidResult(points, *result, 7);
    EXPECT_EQ(result->inertia, 0.0);
  }
  // k = m: every point alone.
  PointSet few{2, {0, 0, 1, 1, 0, 0, 5, 5}};
  KmeansOptions options;
  options.clusters = 4;
  absl::StatusOr<KmeansResult> result = RunKmeans(few, options);
  ASSERT_TRUE(result.ok()) << result.status();
  ExpectValidResult(few, *result, 4);
  EXPECT_EQ(result->inertia, 0.0);
}

// Runs `body` with the processor's kernels and again with the baseline ones.
template <typename Body>
void WithEachKernel(Body body) {
  for (detail::KmeansKernels kernels :
       {detail::KmeansKernels::kAuto, detail::KmeansKernels::kBaseline}) {
    SCOPED_TRACE(kernels == detail::KmeansKernels::kAuto ? "auto kernels" : "baseline kernels");
    detail::SetKmeansKernelsForTesting(kernels);
    body();
  }
  detail::SetKmeansKernelsForTesting(detail::KmeansKernels::kAuto);
}

TEST(KmeansTest, BaselineKernelsGiveTheSameClustering) {
  const Blobs blobs = GaussianBlobs(12, 300, 8, 12);
  std::vector<KmeansResult> results;
  WithEachKernel([&] {
    KmeansOptions options;
    options.clusters = 12;
    absl::StatusOr<KmeansResult> result = RunKmeans(blobs.points, options);
    ASSERT_TRUE(result.ok()) << result.status();
    ExpectValidResult(blobs.points, *result, 12);
    results.push_back(*std::move(result));
  });
  ASSERT_EQ(results.size(), 2u);
  // FMA may break near-ties differently, which these well-separated blobs do not have.
  EXPECT_EQ(results[0].labels, results[1].labels);
  EXPECT_NEAR(results[0].inertia, results[1].inertia, 1e-9 * results[0].inertia);
}

TEST(KmeansTest, EveryDimensionCountAssignsToTheNearestCentre) {
  WithEachKernel([] {
    // d = 1..4 have their own kernels, others the generic one.
    for (uint32_t d : {1u, 2u, 3u, 4u, 5u, 9u}) {
      const PointSet points = UniformPoints(3001, d, d);
      const std::vector<float> centres = *KmeansPlusPlusCentres(points, 37, 3, 0);
      KmeansOptions options;
      options.max_iterations = 1;
      const KmeansResult result = *RunLloyd(points, centres, options);
      for (size_t i = 0; i < points.num_points(); ++i) {
        double best = std::numeric_limits<double>::infinity();
        double own = 0;
        for (uint32_t c = 0; c < 37; ++c) {
          double s = 0;
          for (uint32_t j = 0; j < d; ++j) {
            const double t = points.point(i)[j] - centres[c * d + j];
            s += t * t;
          }
          best = std::min(best, s);
          if (c == result.labels[i].value()) own = s;
        }
        ASSERT_LE(own, best * (1 + 1e-5)) << "d " << d << " point " << i;
      }
    }
  });
}

TEST(KmeansTest, RejectsBadArguments) {
  const PointSet points = UniformPoints(10, 2, 1);
  KmeansOptions options;
  options.clusters = 0;
  EXPECT_THAT(RunKmeans(points, options).status().message(), HasSubstr("clusters"));
  options.clusters = 11;
  EXPECT_THAT(RunKmeans(points, options).status().message(), HasSubstr("clusters"));
  EXPECT_THAT(KmeansPlusPlusCentres(points, 0, 1, 0).status().message(), HasSubstr("clusters"));
  EXPECT_THAT(KmeansPlusPlusCentres(points, 11, 1, 0).status().message(), HasSubstr("clusters"));
  options.clusters = 10;
  EXPECT_TRUE(RunKmeans(points, options).ok());
  options.threads = -1;
  EXPECT_THAT(RunKmeans(points, options).status().message(), HasSubstr("threads"));
  options.threads = 0;
  options.max_iterations = 0;
  EXPECT_THAT(RunKmeans(points, options).status().message(), HasSubstr("max_iterations"));
  options.max_iterations = 10;
  options.tolerance = -1;
  EXPECT_THAT(RunKmeans(points, options).status().message(), HasSubstr("tolerance"));
  options.tolerance = std::nan("");
  EXPECT_THAT(RunKmeans(points, options).status().message(), HasSubstr("tolerance"));

  PointSet bad = points;
  bad.values[5] = std::numeric_limits<float>::quiet_NaN();
  options = {};
  options.clusters = 2;
  absl::Status status = RunKmeans(bad, options).status();
  EXPECT_EQ(status, ValidatePoints(bad));
  EXPECT_FALSE(status.ok());
  PointSet huge{1, {0, 1, 2e17f}};
  EXPECT_THAT(RunKmeans(huge, options).status().message(), HasSubstr("points"));

  options = {};
  EXPECT_THAT(RunLloyd(points, {1, 2, 3}, options).status().message(), HasSubstr("centres"));
  EXPECT_THAT(RunLloyd(points, {}, options).status().message(), HasSubstr("centres"));
  options.clusters = 3;
  EXPECT_THAT(RunLloyd(points, {1, 2, 3, 4}, options).status().message(), HasSubstr("centres"));
  options.clusters = 0;
  EXPECT_THAT(
      RunLloyd(points, {1, std::numeric_limits<float>::infinity()}, options).status().message(),
      HasSubstr("centres"));
  EXPECT_THAT(RunLloyd(points, std::vector<float>(22, 0.0f), options).status().message(),
              HasSubstr("clusters"));
}

TEST(KmeansTest, ACancelFlagReturnsCancelled) {
  const PointSet points = UniformPoints(5000, 3, 11);
  std::atomic<bool> cancel{true};
  for (KmeansOptions::Init init : kBothInits) {
    KmeansOptions options = Options(20, init);
    options.cancel = &cancel;
    EXPECT_EQ(RunKmeans(points, options).status().code(), absl::StatusCode::kCancelled);
  }
  // Set after the first iteration: the second returns CANCELLED.
  cancel = false;
  KmeansOptions options;
  options.clusters = 20;
  options.tolerance = 0;
  options.cancel = &cancel;
  uint32_t iterations = 0;
  options.on_iteration = [&](uint32_t iteration, double) {
    iterations = iteration;
    cancel = true;
  };
  EXPECT_EQ(RunKmeans(points, options).status().code(), absl::StatusCode::kCancelled);
  EXPECT_EQ(iterations, 1u);
}

}  // namespace
}  // namespace mlclust
