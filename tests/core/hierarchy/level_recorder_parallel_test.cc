// LevelRecorder's entry points for PML (RecordMerges, Squash with for_blocks) against the
// one-by-one calls they stand for.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <thread>
#include <utility>
#include <vector>

#include "core/hierarchy/level_recorder.h"
#include "tests/fixtures/recording_sink.h"

namespace mlclust {
namespace {

using Collect = testing::LevelListSink;

// Runs the blocks on two threads, the later half first: the result must not depend on it.
struct TwoThreads {
  template <typename Body>
  void operator()(size_t n, const Body& body) const {
    std::thread later([&] {
      if (n / 2 < n) body(n / 2, n);
    });
    later.join();
    if (n / 2 > 0) body(size_t{0}, n / 2);
  }
};

// Elements e in clusters e / 3 (3 per cluster, ids below 3 * clusters); the energy of a
// cluster is the sum of its elements' squares plus its id, so that every change counts.
struct Clusters {
  explicit Clusters(uint32_t clusters) : label(3 * clusters) {
    for (uint32_t e = 0; e < label.size(); ++e) label[e] = e / 3;
    members.resize(clusters);
    for (uint32_t e = 0; e < label.size(); ++e) members[e / 3].push_back(e);
  }
  double Energy(uint32_t c) const {
    double sum = c;
    for (uint32_t e : members[c]) sum += 1e-3 * e * e;
    return sum;
  }
  void Merge(uint32_t keep, uint32_t gone) {
    for (uint32_t e : members[gone]) {
      label[e] = keep;
      members[keep].push_back(e);
    }
    members[gone].clear();
  }
  std::vector<uint32_t> label;
  std::vector<std::vector<uint32_t>> members;
};

// Two levels of merges of disjoint pairs, 12,000 pairs each (more moves than a squash block
// twice over), then a level with single moves: RecordMerges + Squash(for_blocks) give the
// same triplets in the same order and the same energy bits as Touch/RecordMove pair after
// pair and the plain Squash.
TEST(LevelRecorderParallelTest, RecordMergesAndBlockSquashEqualOneByOne) {
  constexpr uint32_t kClusters = 48000;
  Clusters one(kClusters), two(kClusters);
  LevelRecorder by_one(3 * kClusters, kClusters), by_blocks(3 * kClusters, kClusters);
  by_one.Reset(1.5);
  by_blocks.Reset(1.5);
  Collect sink_one, sink_blocks;
  auto energy_one = [&](uint32_t c) { return one.Energy(c); };
  auto energy_two = [&](uint32_t c) { return two.Energy(c); };
  auto id_of = [](uint32_t e) { return 7 * e + 1; };
  for (uint32_t level = 1; level <= 2; ++level) {
    // Pairs (4k + level - 1 + 2 * (level - 1) ..., ...): disjoint, a mix of keep < gone
    // and keep > gone.
    std::vector<std::pair<uint32_t, uint32_t>> pairs;
    const uint32_t step = 2 * level;
    for (uint32_t c = 0; c + step / 2 < kClusters && pairs.size() < 12000; c += step) {
      const uint32_t a = c, b = c + step / 2;
      pairs.push_back(c % 3 == 0 ? std::make_pair(b, a) : std::make_pair(a, b));
    }
    // The triplets expected, worked out here: each element's first origin, in order.
    std::vector<std::pair<uint32_t, uint32_t>> origin;
    std::vector<uint8_t> seen(3 * kClusters, 0);
    auto note = [&](uint32_t e, uint32_t from) {
      if (!seen[e]) origin.push_back({e, from});
      seen[e] = 1;
    };
    for (const auto& [keep, gone] : pairs) {
      by_one.Touch(keep, energy_one);
      by_one.Touch(gone, energy_one);
      for (uint32_t e : one.members[gone]) {
        by_one.RecordMove(e, gone);
        note(e, gone);
      }
      one.Merge(keep, gone);
    }
    ASSERT_TRUE(by_blocks.RecordMerges(
        pairs, energy_two, [&](uint32_t c) { return std::span<const uint32_t>(two.members[c]); },
        TwoThreads{}));
    // Not at the start of a level any more: refused, nothing recorded.
    EXPECT_FALSE(by_blocks.RecordMerges(
        pairs, energy_two, [&](uint32_t c) { return std::span<const uint32_t>(two.members[c]); }));
    for (const auto& [keep, gone] : pairs) two.Merge(keep, gone);
    // A few elements move on after the merges (one of them back where it was).
    for (Clusters* clusters : {&one, &two}) {
      LevelRecorder& recorder = clusters == &one ? by_one : by_blocks;
      auto energy_of = [&](uint32_t c) { return clusters->Energy(c); };
      for (uint32_t e : {5u, 9u, 3u * pairs[0].second}) {
        const uint32_t from = clusters->label[e], to = e == 5u ? 0u : 2u;
        recorder.Touch(from, energy_of);
        recorder.Touch(to, energy_of);
        recorder.RecordMove(e, from);
        if (clusters == &one) note(e, from);
        auto& list = clusters->members[from];
        list.erase(std::find(list.begin(), list.end(), e));
        clusters->members[to].push_back(e);
        clusters->label[e] = to;
      }
    }
    by_one.Squash(
        energy_one, [&](uint32_t e) { return one.label[e]; }, id_of);
    by_blocks.Squash(
        energy_two, [&](uint32_t e) { return two.label[e]; }, id_of, TwoThreads{});
    ASSERT_TRUE(by_one.Emit(sink_one, level, 0).ok());
    std::vector<uint32_t> expected_element, expected_to, expected_from;
    for (const auto& [e, from] : origin) {
      if (one.label[e] == from) continue;  // came back
      expected_element.push_back(id_of(e));
      expected_to.push_back(one.label[e]);
      expected_from.push_back(from);
    }
    EXPECT_EQ(sink_one.element.back(), expected_element);
    EXPECT_EQ(sink_one.to.back(), expected_to);
    EXPECT_EQ(sink_one.from.back(), expected_from);
    ASSERT_TRUE(by_blocks.Emit(sink_blocks, level, 0).ok());
  }
  ASSERT_EQ(sink_one.element.size(), 2u);
  EXPECT_GT(sink_one.element[0].size(), 20000u);  // squashed in blocks
  EXPECT_EQ(sink_one.element, sink_blocks.element);
  EXPECT_EQ(sink_one.to, sink_blocks.to);
  EXPECT_EQ(sink_one.from, sink_blocks.from);
  EXPECT_EQ(sink_one.energies, sink_blocks.energies);  // bit for bit
  EXPECT_NE(sink_one.energies[0], 1.5);
  EXPECT_EQ(by_one.moves(), by_blocks.moves());
}

}  // namespace
}  // namespace mlclust
