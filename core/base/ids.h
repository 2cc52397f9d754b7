// Strongly typed element and cluster ids.
//
// Faces, vertices, points and clusters are different things; a FaceId cannot be passed
// where a ClusterId is expected. Each id is a 32-bit index; Invalid() (value
// kInvalidValue) marks "none", for example the missing neighbour across a boundary edge.
// It is the one sentinel of each id type: code that works on raw uint32_t indices names
// it as FaceId::kInvalidValue, ClusterId::kInvalidValue, ..., not as its own constant.
#ifndef MLCLUST_CORE_BASE_IDS_H_
#define MLCLUST_CORE_BASE_IDS_H_

#include <cstdint>
#include <functional>
#include <limits>

namespace mlclust {

template <typename Tag>
class StrongId {
 public:
  using ValueType = uint32_t;
  static constexpr ValueType kInvalidValue = std::numeric_limits<ValueType>::max();

  constexpr StrongId() = default;
  constexpr explicit StrongId(ValueType value) : value_(value) {}

  static constexpr StrongId Invalid() { return StrongId(); }
  constexpr ValueType value() const { return value_; }
  constexpr bool valid() const { return value_ != kInvalidValue; }

  friend constexpr bool operator==(StrongId a, StrongId b) { return a.value_ == b.value_; }
  friend constexpr bool operator!=(StrongId a, StrongId b) { return a.value_ != b.value_; }
  friend constexpr bool operator<(StrongId a, StrongId b) { return a.value_ < b.value_; }
  friend constexpr bool operator>(StrongId a, StrongId b) { return a.value_ > b.value_; }

  template <typename H>
  friend H AbslHashValue(H h, StrongId id) {
    return H::combine(std::move(h), id.value_);
  }

 private:
  ValueType value_ = kInvalidValue;
};

using FaceId = StrongId<struct FaceTag>;
using VertexId = StrongId<struct VertexTag>;
using ClusterId = StrongId<struct ClusterTag>;
using PointId = StrongId<struct PointTag>;

}  // namespace mlclust

#endif  // MLCLUST_CORE_BASE_IDS_H_
