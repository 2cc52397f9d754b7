// A 64-bit FNV-1a hash over a hierarchy's levels as a LevelSink hears them: the start's
// labels, count and energy bits, then per level its count, energy bits, number of triplets
// and the triplets. Two runs with equal hashes gave the same levels (labels included), bit
// for bit; benches print it as a fingerprint to compare builds with `diff`.
#ifndef MLCLUST_BENCH_LEVEL_HASH_H_
#define MLCLUST_BENCH_LEVEL_HASH_H_

#include <cstdint>
#include <cstring>
#include <span>

#include "core/base/ids.h"
#include "core/hierarchy/hierarchy.h"

namespace mlclust::bench {

class LevelHash {
 public:
  void Start(std::span<const ClusterId> labels, uint32_t count, double energy) {
    for (ClusterId c : labels) Mix(c.value());
    Mix(count);
    MixDouble(energy);
  }
  void Level(const LevelMoves& level) {
    Mix(level.cluster_count);
    MixDouble(level.energy);
    Mix(static_cast<uint64_t>(level.element.size()));
    for (size_t i = 0; i < level.element.size(); ++i) {
      Mix(level.element[i]);
      Mix(level.to_cluster[i]);
      Mix(level.from_cluster[i]);
    }
  }
  uint64_t value() const { return state_; }

 private:
  // FNV-1a over the value's 8 bytes, least significant first.
  void Mix(uint64_t value) {
    for (int b = 0; b < 8; ++b) {
      state_ ^= (value >> (8 * b)) & 0xff;
      state_ *= 0x100000001b3ull;  // the 64-bit FNV prime
    }
  }
  void MixDouble(double value) {
    uint64_t bits = 0;
    std::memcpy(&bits, &value, sizeof bits);
    Mix(bits);
  }
  uint64_t state_ = 0xcbf29ce484222325ull;  // the 64-bit FNV offset basis
};

}  // namespace mlclust::bench

#endif  // MLCLUST_BENCH_LEVEL_HASH_H_
