#include "core/hierarchy/model_selection.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>

#include "core/base/random.h"
#include "core/cluster/kmeans.h"
#include "tests/fixtures/test_points.h"

namespace mlclust {
namespace {

using ::testing::HasSubstr;

constexpr double kInfinity = std::numeric_limits<double>::infinity();

using testing::Blobs;
using testing::GaussianBlobs;

// Cluster sizes and SSE (about the double-precision means) of a labelling with labels 0..k-1.
struct Partition {
  std::vector<uint64_t> sizes;
  double sse = 0;
};

Partition Measure(const PointSet& points, const std::vector<uint32_t>& labels, uint32_t k) {
  const uint32_t d = points.dims;
  std::vector<double> sums(size_t{k} * d, 0.0);
  Partition partition;
  partition.sizes.assign(k, 0);
  for (size_t i = 0; i < labels.size(); ++i) {
    ++partition.sizes[labels[i]];
    for (uint32_t j = 0; j < d; ++j) sums[labels[i] * d + j] += points.point(i)[j];
  }
  for (size_t i = 0; i < labels.size(); ++i) {
    for (uint32_t j = 0; j < d; ++j) {
      const double t = points.point(i)[j] - sums[labels[i] * d + j] / partition.sizes[labels[i]];
      partition.sse += t * t;
    }
  }
  return partition;
}

double Bic(const PointSet& points, const std::vector<uint32_t>& labels, uint32_t k) {
  const Partition partition = Measure(points, labels, k);
  return SphericalGaussianBic(partition.sizes, partition.sse, points.num_points(), points.dims);
}

TEST(SphericalGaussianBicTest, HandComputedExample) {
  // Points 0, 2 | 10, 12 in one dimension: R = 4, K = 2, R_n = 2, SSE = 4, M = 1.
  // s^2 = 4 / (1 (4 - 2)) = 2; log L = 4 ln(1/2) - 2 ln(4 pi) - 1; p = 1 + 2 + 1 = 4;
  // BIC = log L - 2 ln 4 = -4 ln 4 - 2 ln(4 pi) - 1 = -11.60722594...
  const std::vector<uint64_t> sizes = {2, 2};
  const double bic = SphericalGaussianBic(sizes, 4.0, 4, 1);
  EXPECT_NEAR(bic, -4 * std::log(4.0) - 2 * std::log(4 * std::numbers::pi) - 1, 1e-12);
  EXPECT_NEAR(bic, -11.60722594, 1e-8);

  // The same log-likelihood summed point by point: ln(R_n / R) + ln N(x; mu_n, s^2).
  const double x[] = {0, 2, 10, 12};
  const double mu[] = {1, 1, 11, 11};
  double log_likelihood = 0;
  for (int i = 0; i < 4; ++i) {
    log_likelihood += std::log(0.5) - 0.5 * std::log(2 * std::numbers::pi * 2) -
                      (x[i] - mu[i]) * (x[i] - mu[i]) / (2 * 2);
  }
  EXPECT_NEAR(bic, log_likelihood - 0.5 * 4 * std::log(4.0), 1e-12);

  // Zero sizes are skipped; the size-term form agrees.
  const std::vector<uint64_t> with_empty = {2, 0, 2};
  EXPECT_EQ(SphericalGaussianBic(with_empty, 4.0, 4, 1), bic);
  EXPECT_NEAR(SphericalGaussianBicFromSizeTerm(2 * 2 * std::log(2.0), 2, 4.0, 4, 1), bic, 1e-12);

  // One cluster of 3 points at 0, 1, 2 in 2-D (second coordinate 0): SSE = 2, R = 3, M = 2.
  // s^2 = 2 / (2 * 2) = 0.5; log L = 0 - 3 ln(pi) - 2; p = 3; BIC = log L - 1.5 ln 3.
  const std::vector<uint64_t> one = {3};
  EXPECT_NEAR(SphericalGaussianBic(one, 2.0, 3, 2),
              -3 * std::log(std::numbers::pi) - 2 - 1.5 * std::log(3.0), 1e-12);
}

TEST(SphericalGaussianBicTest, DegenerateLevelsScoreMinusInfinity) {
  // Every point alone: no degree of freedom for the variance.
  const std::vector<uint64_t> singletons = {1, 1, 1};
  EXPECT_EQ(SphericalGaussianBic(singletons, 0.0, 3, 2), -kInfinity);
  // Point masses (duplicate points), or rounding below zero: the variance estimate is 0.
  const std::vector<uint64_t> pairs = {2, 2};
  EXPECT_EQ(SphericalGaussianBic(pairs, 0.0, 4, 3), -kInfinity);
  EXPECT_EQ(SphericalGaussianBic(pairs, -1e-12, 4, 3), -kInfinity);
  EXPECT_TRUE(std::isfinite(SphericalGaussianBic(pairs, 1e-12, 4, 3)));
  // So a few duplicate points, which a bottom-up hierarchy merges first at no cost, do not
  // decide the choice; all levels degenerate (every point the same): one cluster.
  const std::vector<uint32_t> counts = {3, 2, 1};
  const std::vector<BicLevel> duplicates = {
      {3, 0.0, 0.0}, {2, 0.0, 2 * std::log(2.0)}, {1, 0.0, 3 * std::log(3.0)}};
  absl::StatusOr<BicChoice> choice = ChooseByBic(duplicates, 3, 2);
  ASSERT_TRUE(choice.ok());
  EXPECT_EQ(choice->best_k, 1u);
  EXPECT_EQ(choice->first_decrease_k, 1u);
}

TEST(SphericalGaussianBicTest, SizeEntropyTrackerMatchesDirectSumUnderManyChanges) {
  SizeEntropyTracker tracker;
  EXPECT_EQ(tracker.size_term(), 0.0);
  std::vector<uint64_t> sizes(50, 0);
  Random random(3);
  for (uint32_t c = 0; c < 50; ++c) {
    sizes[c] = random.Below(1000);
    tracker.Set(c, sizes[c]);
  }
  for (int step = 0; step < 1000000; ++step) {
    const uint32_t from = static_cast<uint32_t>(random.Below(50));
    if (sizes[from] == 0) continue;
    const uint32_t to = static_cast<uint32_t>(random.Below(50));
    tracker.Move(from, to);
    --sizes[from];
    ++sizes[to];
  }
  double direct = 0;
  uint64_t points = 0, clusters = 0;
  for (uint32_t c = 0; c < 50; ++c) {
    EXPECT_EQ(tracker.size(c), sizes[c]);
    if (sizes[c] > 0) direct += sizes[c] * std::log(static_cast<double>(sizes[c]));
    points += sizes[c];
    clusters += sizes[c] > 0;
  }
  EXPECT_NEAR(tracker.size_term(), direct, 1e-12 * direct);
  EXPECT_EQ(tracker.num_points(), points);
  EXPECT_EQ(tracker.num_clusters(), clusters);
  EXPECT_EQ(tracker.size(1000), 0u);  // beyond the ids seen
  tracker.Set(1000, 3);
  EXPECT_EQ(tracker.num_clusters(), clusters + 1);
  EXPECT_NEAR(tracker.size_term(), direct + 3 * std::log(3.0), 1e-12 * direct);
}

// The true partition of K well-separated Gaussians scores higher than every partition with
// one cluster fewer (two true clusters merged) and every one with one more (a true cluster
// split in two by k-means).
TEST(SphericalGaussianBicTest, TrueNumberOfClustersScoresHighest) {
  for (uint32_t clusters : {5u, 10u, 20u}) {
    const Blobs blobs = GaussianBlobs(clusters, 500, 8, clusters);
    const double truth = Bic(blobs.points, blobs.truth, clusters);
    for (uint32_t a = 0; a < clusters; ++a) {
      for (uint32_t b = a + 1; b < clusters; ++b) {
        std::vector<uint32_t> merged = blobs.truth;
        for (uint32_t& label : merged) {
          if (label == b) {
            label = a;
          } else if (label > b) {
            --label;  // labels 0..K-2
          }
        }
        EXPECT_LT(Bic(blobs.points, merged, clusters - 1), truth)
            << "K " << clusters << " merging " << a << " and " << b;
      }
    }
    for (uint32_t split = 0; split < clusters; ++split) {
      PointSet members{3, {}};
      std::vector<size_t> index;
      for (size_t i = 0; i < blobs.truth.size(); ++i) {
        if (blobs.truth[i] != split) continue;
        index.push_back(i);
        const auto p = blobs.points.point(i);
        members.values.insert(members.values.end(), p.begin(), p.end());
      }
      KmeansOptions options;
      options.clusters = 2;
      const KmeansResult halves = *RunKmeans(members, options);
      std::vector<uint32_t> labels = blobs.truth;
      for (size_t n = 0; n < index.size(); ++n) {
        if (halves.labels[n].value() == 1) labels[index[n]] = clusters;
      }
      EXPECT_LT(Bic(blobs.points, labels, clusters + 1), truth)
          << "K " << clusters << " splitting " << split;
    }
  }
}

// Issue 26 item 4: section 6.6's rule (stop merging when the BIC starts to fall, in the
// hierarchy's own order) beside the highest BIC. A hierarchy from 8 clusters to 1 whose BIC
// wobbles near its fine end (K = 8: 4, K = 7: 5, K = 6: 3): the text's rule stops at K = 7,
// the highest BIC is at K = 3, and read from few to many the first decrease is at K = 3.
TEST(ChooseByBicTest, TheTextsMergingRuleStopsAtTheFirstFallAndDiffersFromTheMaximum) {
  const std::vector<uint32_t> counts = {8, 7, 6, 5, 4, 3, 2, 1};
  BicChoice choice = ChooseByScore(counts, {4, 5, 3, 6, 8, 9, 2, 0});
  EXPECT_EQ(choice.merging_first_decrease_level, 1u);
  EXPECT_EQ(choice.merging_first_decrease_k, 7u);
  EXPECT_EQ(choice.best_k, 3u);
  EXPECT_EQ(choice.first_decrease_k, 3u);
  // Rising all the way as it merges: the last level.
  choice = ChooseByScore(counts, {0, 1, 2, 3, 4, 5, 6, 7});
  EXPECT_EQ(choice.merging_first_decrease_level, 7u);
  EXPECT_EQ(choice.merging_first_decrease_k, 1u);
  // Degenerate levels (the first level of a bottom-up hierarchy) are skipped; equal scores
  // are no fall.
  choice = ChooseByScore(counts, {-kInfinity, 2, 2, 3, 1, 0, 0, 0});
  EXPECT_EQ(choice.merging_first_decrease_k, 5u);
  // All degenerate: the best level, the fewest clusters.
  choice = ChooseByScore(std::vector<uint32_t>{3, 2, 1}, {-kInfinity, -kInfinity, -kInfinity});
  EXPECT_EQ(choice.merging_first_decrease_level, 2u);
}

TEST(ChooseByBicTest, ChooseByScoreBestAndFirstDecrease) {
  // A hierarchy from 6 clusters down to 1. From few to many: K=1: 0, 2: 2, 3: 4, 4: 5, then
  // K=5: 3 is the first decrease, so the first-decrease level is K=4 (level 2); the maximum
  // is at K=6 (level 0).
  const std::vector<uint32_t> counts = {6, 5, 4, 3, 2, 1};
  BicChoice choice = ChooseByScore(counts, {10, 3, 5, 4, 2, 0});
  EXPECT_EQ(choice.best_level, 0u);
  EXPECT_EQ(choice.best_k, 6u);
  EXPECT_EQ(choice.first_decrease_level, 2u);
  EXPECT_EQ(choice.first_decrease_k, 4u);
  EXPECT_THAT(choice.bic, ::testing::ElementsAre(10, 3, 5, 4, 2, 0));

  // Never decreasing: the most clusters. Ties for the best: the fewest clusters.
  choice = ChooseByScore(counts, {7, 7, 5, 4, 2, 0});
  EXPECT_EQ(choice.best_k, 5u);
  EXPECT_EQ(choice.first_decrease_k, 6u);
  EXPECT_EQ(choice.first_decrease_level, 0u);

  // Decreasing at once: one cluster.
  choice = ChooseByScore(counts, {0, 1, 2, 3, 4, 5});
  EXPECT_EQ(choice.first_decrease_k, 1u);
  EXPECT_EQ(choice.best_k, 1u);
  EXPECT_EQ(choice.best_level, 5u);

  // Infinities are ordered as numbers: -infinity (undefined) is never chosen over a number.
  choice = ChooseByScore(counts, {-kInfinity, -kInfinity, 2, 1, 0, -1});
  EXPECT_EQ(choice.best_k, 4u);
  EXPECT_EQ(choice.first_decrease_k, 4u);
  choice = ChooseByScore(counts, {-kInfinity, kInfinity, kInfinity, 1, 0, -1});
  EXPECT_EQ(choice.best_k, 4u);
  EXPECT_EQ(choice.first_decrease_k, 5u);

  // Levels that share a cluster count (a merge, then an optimisation that lowers the energy)
  // take part through the larger score; the order of the input does not matter.
  // K=3 takes part with 5 (not the later 2), so the scores rise all the way: 0, 4, 5, 6.
  const std::vector<uint32_t> repeated = {4, 4, 3, 3, 2, 1};
  choice = ChooseByScore(repeated, {1, 6, 5, 2, 4, 0});
  EXPECT_EQ(choice.first_decrease_k, 4u);
  EXPECT_EQ(choice.first_decrease_level, 1u);
  EXPECT_EQ(choice.best_level, 1u);
  const std::vector<uint32_t> shuffled = {1, 3, 4, 2, 3, 4};
  choice = ChooseByScore(shuffled, {0, 5, 1, 4, 2, 6});
  EXPECT_EQ(choice.first_decrease_k, 4u);
  EXPECT_EQ(choice.first_decrease_level, 5u);
  EXPECT_EQ(choice.best_level, 5u);
  // Equal counts and equal scores: the later level.
  const std::vector<uint32_t> twins = {2, 2, 1};
  choice = ChooseByScore(twins, {3, 3, 0});
  EXPECT_EQ(choice.best_level, 1u);
  EXPECT_EQ(choice.first_decrease_level, 1u);
}

// A bottom-up Ward hierarchy (every point alone, then always the merge of least SSE
// increase) of `points`, fed to `sink` as a driver would: the smaller cluster's points move
// to the larger, the level's energy is the SSE.
void WardHierarchy(const PointSet& points, LevelSink& sink) {
  const size_t n = points.num_points();
  const uint32_t d = points.dims;
  std::vector<std::vector<uint32_t>> members(n);
  std::vector<double> sums(n * d);
  std::vector<ClusterId> labels(n);
  for (size_t i = 0; i < n; ++i) {
    members[i] = {static_cast<uint32_t>(i)};
    for (uint32_t j = 0; j < d; ++j) sums[i * d + j] = points.point(i)[j];
    labels[i] = ClusterId(static_cast<uint32_t>(i));
  }
  auto cost = [&](size_t a, size_t b) {
    const double na = members[a].size(), nb = members[b].size();
    double t2 = 0;
    for (uint32_t j = 0; j < d; ++j) {
      const double t = sums[a * d + j] / na - sums[b * d + j] / nb;
      t2 += t * t;
    }
    return na * nb / (na + nb) * t2;
  };
  std::vector<bool> alive(n, true);
  std::vector<size_t> nearest(n);
  std::vector<double> nearest_cost(n);
  auto refresh = [&](size_t a) {
    nearest_cost[a] = kInfinity;
    for (size_t b = 0; b < n; ++b) {
      if (b == a || !alive[b]) continue;
      const double c = cost(a, b);
      if (c < nearest_cost[a]) {
        nearest_cost[a] = c;
        nearest[a] = b;
      }
    }
  };
  for (size_t a = 0; a < n; ++a) refresh(a);
  ASSERT_TRUE(sink.OnStart(labels, static_cast<uint32_t>(n), 0.0).ok());
  double sse = 0;
  std::vector<uint32_t> element, to, from;
  for (size_t clusters = n; clusters > 1; --clusters) {
    size_t a = n;
    for (size_t c = 0; c < n; ++c) {
      if (alive[c] && (a == n || nearest_cost[c] < nearest_cost[a])) a = c;
    }
    size_t b = nearest[a];
    sse += nearest_cost[a];
    if (members[a].size() < members[b].size()) std::swap(a, b);
    element = members[b];
    to.assign(element.size(), static_cast<uint32_t>(a));
    from.assign(element.size(), static_cast<uint32_t>(b));
    members[a].insert(members[a].end(), members[b].begin(), members[b].end());
    members[b].clear();
    for (uint32_t j = 0; j < d; ++j) sums[a * d + j] += sums[b * d + j];
    alive[b] = false;
    for (size_t c = 0; c < n; ++c) {
      if (!alive[c] || c == a) continue;
      if (nearest[c] == a || nearest[c] == b) {
        refresh(c);
      } else if (const double cc = cost(c, a); cc < nearest_cost[c]) {
        nearest_cost[c] = cc;
        nearest[c] = a;
      }
    }
    refresh(a);
    LevelMoves level;
    level.cluster_count = static_cast<uint32_t>(clusters - 1);
    level.energy = sse;
    level.element = element;
    level.to_cluster = to;
    level.from_cluster = from;
    ASSERT_TRUE(sink.OnLevel(level).ok());
  }
}

TEST(BicLevelRecorderTest, WardHierarchyChoosesTheTrueNumberOfClusters) {
  for (uint32_t clusters : {3u, 5u, 8u}) {
    const Blobs blobs = GaussianBlobs(clusters, 120, 8, 100 + clusters);
    BicLevelRecorder recorder;
    WardHierarchy(blobs.points, recorder);
    const size_t n = blobs.points.num_points();
    ASSERT_EQ(recorder.levels().size(), n);
    EXPECT_EQ(recorder.num_points(), n);
    // Sizes kept from the moves agree with the labels' sizes at a spot check: one cluster.
    EXPECT_NEAR(recorder.levels().back().size_term, n * std::log(double(n)), 1e-9 * n);
    EXPECT_EQ(recorder.levels().back().clusters, 1u);
    absl::StatusOr<BicChoice> choice = ChooseByBic(recorder.levels(), n, 3);
    ASSERT_TRUE(choice.ok()) << choice.status();
    EXPECT_EQ(choice->best_k, clusters);
    EXPECT_EQ(choice->first_decrease_k, clusters);
    EXPECT_EQ(choice->bic[0], -kInfinity);  // every point alone
    // Read from the fine end instead, the BIC falls within the first few levels: the reason
    // the first decrease is taken from the coarse end (see BicChoice).
    size_t top_decrease = 1;
    while (top_decrease + 1 < n && !(choice->bic[top_decrease + 1] < choice->bic[top_decrease])) {
      ++top_decrease;
    }
    EXPECT_LT(top_decrease, n / 10) << "K " << clusters;
  }
}

TEST(ChooseByBicTest, KmeansSweepChoosesTheTrueNumberOfClusters) {
  const Blobs blobs = GaussianBlobs(6, 300, 8, 17);
  std::vector<BicLevel> levels;
  for (uint32_t k = 1; k <= 12; ++k) {
    KmeansOptions options;
    options.clusters = k;
    const KmeansResult result = *RunKmeans(blobs.points, options);
    SizeEntropyTracker sizes;
    for (ClusterId label : result.labels) sizes.Set(label.value(), sizes.size(label.value()) + 1);
    levels.push_back({k, result.inertia, sizes.size_term()});
  }
  absl::StatusOr<BicChoice> choice = ChooseByBic(levels, blobs.points.num_points(), 3);
  ASSERT_TRUE(choice.ok()) << choice.status();
  EXPECT_EQ(choice->best_k, 6u);
  EXPECT_EQ(choice->best_level, 5u);
  EXPECT_EQ(choice->first_decrease_k, 6u);
}

TEST(ChooseByBicTest, RejectsBadLevels) {
  EXPECT_THAT(ChooseByBic({}, 10, 3).status().message(), HasSubstr("levels"));
  const std::vector<BicLevel> ok = {{2, 1.0, 5.0}};
  EXPECT_THAT(ChooseByBic(ok, 0, 3).status().message(), HasSubstr("num_points"));
  EXPECT_THAT(ChooseByBic(ok, 10, 0).status().message(), HasSubstr("dims"));
  EXPECT_TRUE(ChooseByBic(ok, 10, 3).ok());
  const std::vector<BicLevel> none = {{0, 1.0, 5.0}};
  EXPECT_THAT(ChooseByBic(none, 10, 3).status().message(), HasSubstr("level 0"));
  const std::vector<BicLevel> many = {{2, 1.0, 5.0}, {11, 1.0, 5.0}};
  EXPECT_THAT(ChooseByBic(many, 10, 3).status().message(), HasSubstr("level 1"));
  const std::vector<BicLevel> nan = {{2, std::nan(""), 5.0}};
  EXPECT_THAT(ChooseByBic(nan, 10, 3).status().message(), HasSubstr("sse"));
}

TEST(BicLevelRecorderTest, RejectsInconsistentLevels) {
  const std::vector<ClusterId> labels = {ClusterId(0), ClusterId(0), ClusterId(4)};
  {
    BicLevelRecorder recorder;
    EXPECT_EQ(recorder.OnLevel({}).code(), absl::StatusCode::kFailedPrecondition);
    EXPECT_THAT(recorder.OnStart(labels, 3, 1.0).message(), HasSubstr("cluster_count"));
  }
  BicLevelRecorder recorder;
  ASSERT_TRUE(recorder.OnStart(labels, 2, 1.0).ok());
  EXPECT_EQ(recorder.OnStart(labels, 2, 1.0).code(), absl::StatusCode::kFailedPrecondition);
  const uint32_t element[] = {1};
  const uint32_t to[] = {4};
  const uint32_t wrong_from[] = {3};
  LevelMoves level;
  level.cluster_count = 2;
  level.element = element;
  level.to_cluster = to;
  level.from_cluster = wrong_from;
  EXPECT_THAT(recorder.OnLevel(level).message(), HasSubstr("empty"));
  BicLevelRecorder fresh;
  ASSERT_TRUE(fresh.OnStart(labels, 2, 1.0).ok());
  const uint32_t from[] = {0};
  level.from_cluster = from;
  EXPECT_TRUE(fresh.OnLevel(level).ok());  // sizes {1, 2}
  EXPECT_EQ(fresh.levels().size(), 2u);
  EXPECT_NEAR(fresh.levels()[1].size_term, 2 * std::log(2.0), 1e-15);
  level.cluster_count = 2;
  const uint32_t last_from[] = {0};
  level.from_cluster = last_from;
  EXPECT_THAT(fresh.OnLevel(level).message(), HasSubstr("cluster_count"));  // now 1 cluster
  level.element = {};
  EXPECT_THAT(fresh.OnLevel(level).message(), HasSubstr("elements"));
}

}  // namespace
}  // namespace mlclust
