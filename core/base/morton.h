// Morton (Z-order) codes: 10 bits per axis interleaved into 30 bits, x lowest.
#ifndef MLCLUST_CORE_BASE_MORTON_H_
#define MLCLUST_CORE_BASE_MORTON_H_

#include <cstdint>

namespace mlclust {

// The 10 low bits of v spread to every third bit (bit i to bit 3i).
inline uint32_t SpreadBits(uint32_t v) {
  v &= 0x3ffu;
  v = (v | (v << 16)) & 0x030000ffu;
  v = (v | (v << 8)) & 0x0300f00fu;
  v = (v | (v << 4)) & 0x030c30c3u;
  v = (v | (v << 2)) & 0x09249249u;
  return v;
}

// The code of the cell (x, y, z), each in [0, 1023].
inline uint32_t MortonCode(uint32_t x, uint32_t y, uint32_t z) {
  return SpreadBits(x) | (SpreadBits(y) << 1) | (SpreadBits(z) << 2);
}

}  // namespace mlclust

#endif  // MLCLUST_CORE_BASE_MORTON_H_
