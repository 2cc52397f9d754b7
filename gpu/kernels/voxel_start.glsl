// The voxel-grid start on the GPU (voxel_start.h, section 6.2, eqs. 6.2/6.3): every point
// to its cell, the occupied cells compacted to cluster ids in order of their first point
// (VoxelGridStart's numbering), the face-sharing occupied cells as the first neighbours.
// Cells live in an open-addressing hash table of 2^b slots keyed by the cell's
// coordinates; a slot holds (representative point + 1, first point): the representative
// is whichever point claimed the slot, the first point the smallest index in the cell
// (atomicMin). A cell's coordinates are recomputed from a point wherever needed (never
// stored), exactly as the CPU computes them: the offset from the box's low corner in
// float, divided by the box's extent in double, times the cells on the axis, clamped and
// truncated (`precise`: no fused multiply-add).
//   u_phase 0  bounds    per 64 points: min and max per axis, then one atomicMin/Max each
//                        on an order-preserving key of the float
//   u_phase 1  insert    per point: its cell's slot (point_slot), the first point; a newly
//                        claimed slot counts in counters[1] (the occupied cells)
//   u_phase 2  count     \
//   u_phase 3  scan       | stream compaction of the first points, in point order, as
//   u_phase 4  top        | pml_compact.glsl (chunks of 32, groups of 256): each cell's
//   u_phase 5  write     /  cluster id (slot_cluster) and first point (cluster_first)
//   u_phase 6  label     per point: its cell's cluster
//   u_phase 7  neighbours per cluster: the occupied cell one step up (2j) and down (2j + 1)
//                        each axis j, else none (0xFFFFFFFF)
// After the prelude of gpu/context/compute.h, before compact_scan.glsl (phases 3 and 4).
layout(std430, binding = 0) readonly buffer Points { float points[]; };  // m x d
struct Axis {
  double span;  // hi - lo in double, as the CPU's
  float lo;
  uint cells;  // cells on this axis
};
layout(std430, binding = 1) readonly buffer Axes { Axis axes[]; };
layout(std430, binding = 2) buffer Bounds { uint bounds[]; };  // d minima, then d maxima
layout(std430, binding = 3) buffer PointSlot { uint point_slot[]; };
layout(std430, binding = 4) buffer Table { uint table[]; };  // (representative + 1, first)
layout(std430, binding = 5) buffer ChunkCount { uint chunk_count[]; };
layout(std430, binding = 6) buffer GroupTotal { uint group_total[]; };
layout(std430, binding = 7) buffer Counters { uint counters[]; };  // [0] clusters, [1] cells
layout(std430, binding = 8) buffer SlotCluster { uint slot_cluster[]; };
layout(std430, binding = 9) buffer ClusterFirst { uint cluster_first[]; };
layout(std430, binding = 10) buffer Labels { uint labels[]; };
layout(std430, binding = 11) buffer Neighbours { uint neighbours[]; };  // k x 2d
layout(location = 0) uniform uint u_count;  // points, chunks, groups or clusters
layout(location = 1) uniform uint u_phase;
layout(location = 2) uniform uint u_dims;
layout(location = 3) uniform uint u_mask;  // slots - 1
const uint kChunk = 32u;
const uint kGroup = 256u;
const uint kNone = 0xFFFFFFFFu;
const uint kMaxDims = 64u;  // kVoxelStartMaxDims

void ScanChunkCounts(uint group);                 // compact_scan.glsl
void ScanGroupTotals(uint invocation, uint slot);  // compact_scan.glsl

uint FloatKey(float f) {
  uint bits = floatBitsToUint(f);
  return (bits & 0x80000000u) != 0u ? ~bits : (bits | 0x80000000u);
}

uint CellOf(uint i, uint j) {
  precise float diff = points[i * u_dims + j] - axes[j].lo;
  double span = axes[j].span;
  precise double t = span > 0.0LF ? double(diff) / span : 0.0LF;
  precise double x = t * double(axes[j].cells);
  return uint(min(double(axes[j].cells - 1u), x));
}

uint HashCell(uint cell[kMaxDims]) {
  uint h = 2166136261u;
  for (uint j = 0u; j < u_dims; ++j) {
    h = (h ^ cell[j]) * 16777619u;
    h ^= h >> 15;
  }
  h ^= h >> 16;
  h *= 0x85ebca6bu;
  h ^= h >> 13;
  h *= 0xc2b2ae35u;
  h ^= h >> 16;
  return h;
}

bool SameCell(uint point, uint cell[kMaxDims]) {
  for (uint j = 0u; j < u_dims; ++j) {
    if (CellOf(point, j) != cell[j]) return false;
  }
  return true;
}

// The slot of `cell`, or kNone where no point lies in it.
uint FindSlot(uint cell[kMaxDims]) {
  uint slot = HashCell(cell) & u_mask;
  for (uint probe = 0u; probe <= u_mask; ++probe) {
    uint representative = table[2u * slot];
    if (representative == 0u) return kNone;
    if (SameCell(representative - 1u, cell)) return slot;
    slot = (slot + 1u) & u_mask;
  }
  return kNone;
}

void main() {
  uint i = LinearInvocationIndex();
  if (u_phase == 0u) {
    uint begin = i * 64u;
    if (begin >= u_count) return;
    uint end = min(begin + 64u, u_count);
    for (uint j = 0u; j < u_dims; ++j) {
      float lo = points[begin * u_dims + j];
      float hi = lo;
      for (uint p = begin + 1u; p < end; ++p) {
        float v = points[p * u_dims + j];
        lo = min(lo, v);
        hi = max(hi, v);
      }
      atomicMin(bounds[j], FloatKey(lo));
      atomicMax(bounds[u_dims + j], FloatKey(hi));
    }
    return;
  }
  if (u_phase == 3u) {
    ScanChunkCounts(i);
    return;
  }
  if (u_phase == 4u) {
    ScanGroupTotals(i, 0u);
    return;
  }
  if (u_phase == 2u || u_phase == 5u) {
    uint begin = i * kChunk;
    if (begin >= u_count) return;
    uint end = min(begin + kChunk, u_count);
    if (u_phase == 2u) {
      uint count = 0u;
      for (uint p = begin; p < end; ++p) count += table[2u * point_slot[p] + 1u] == p ? 1u : 0u;
      chunk_count[i] = count;
      return;
    }
    uint at = chunk_count[i] + group_total[i / kGroup];
    for (uint p = begin; p < end; ++p) {
      uint slot = point_slot[p];
      if (table[2u * slot + 1u] != p) continue;
      slot_cluster[slot] = at;
      cluster_first[at] = p;
      ++at;
    }
    return;
  }
  if (i >= u_count) return;
  if (u_phase == 1u) {
    uint cell[kMaxDims];
    for (uint j = 0u; j < u_dims; ++j) cell[j] = CellOf(i, j);
    uint slot = HashCell(cell) & u_mask;
    for (uint probe = 0u; probe <= u_mask; ++probe) {
      uint previous = atomicCompSwap(table[2u * slot], 0u, i + 1u);
      if (previous == 0u) atomicAdd(counters[1], 1u);
      if (previous == 0u || SameCell(previous - 1u, cell)) {
        atomicMin(table[2u * slot + 1u], i);
        point_slot[i] = slot;
        return;
      }
      slot = (slot + 1u) & u_mask;
    }
    return;
  }
  if (u_phase == 6u) {
    labels[i] = slot_cluster[point_slot[i]];
    return;
  }
  // Phase 7: per cluster, the face-sharing occupied cells.
  uint cell[kMaxDims];
  uint first = cluster_first[i];
  for (uint j = 0u; j < u_dims; ++j) cell[j] = CellOf(first, j);
  for (uint j = 0u; j < u_dims; ++j) {
    uint own = cell[j];
    for (uint side = 0u; side < 2u; ++side) {
      uint found = kNone;
      if (side == 0u || own != 0u) {
        cell[j] = side == 0u ? own + 1u : own - 1u;
        uint slot = FindSlot(cell);
        if (slot != kNone) found = slot_cluster[slot];
        cell[j] = own;
      }
      neighbours[i * 2u * u_dims + 2u * j + side] = found;
    }
  }
}
