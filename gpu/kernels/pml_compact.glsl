// PML on the GPU (pml_levels.h): stream compaction in element order, in chunks of
// kChunk = 32 elements (one invocation each) and groups of kGroup = 256 chunks:
//   u_phase 0  count   per chunk: the elements kept (chunk_count)
//   u_phase 1  scan    per group: exclusive scan of its chunks' counts in place, the
//                      group's total (group_total)
//   u_phase 2  top     one invocation: exclusive scan of the group totals in place, the
//                      grand total to counters[u_slot]
//   u_phase 3  write   per chunk: its kept elements from offset chunk_count[chunk] +
//                      group_total[chunk / kGroup], in order
// u_kind 0, the faces: a face is kept where its cluster merged away (remap[label] !=
// label); it is written as the triplet (face, new, old) and relabelled. u_kind 1, the
// directed cluster edges (src, dst): an edge is kept where remap[src] != remap[dst] and
// written relabelled to edges_out. u_kind 2, the directed face edges (f, g) after BB moves
// (face_edges, every one of the mesh): an edge is kept where labels[f] != labels[g] and
// written as (labels[f], labels[g]) to edges_out. After the prelude of gpu/context/compute.h,
// before compact_scan.glsl (phases 1 and 2).
layout(std430, binding = 2) buffer Labels { uint labels[]; };
layout(std430, binding = 3) readonly buffer Remap { uint remap[]; };
layout(std430, binding = 4) readonly buffer EdgesIn { uint edges_in[]; };
layout(std430, binding = 5) writeonly buffer EdgesOut { uint edges_out[]; };
layout(std430, binding = 6) readonly buffer FaceEdges { uint face_edges[]; };  // kind 2 only
layout(std430, binding = 11) buffer ChunkCount { uint chunk_count[]; };
layout(std430, binding = 12) buffer GroupTotal { uint group_total[]; };
layout(std430, binding = 13) buffer Counters { uint counters[]; };
layout(std430, binding = 14) writeonly buffer Triplets { uint triplets[]; };  // 3 per face
layout(location = 0) uniform uint u_count;  // elements (phases 0, 3), chunks (1), groups (2)
layout(location = 1) uniform uint u_phase;
layout(location = 2) uniform uint u_kind;
layout(location = 3) uniform uint u_slot;
const uint kChunk = 32u;   // kPmlChunk
const uint kGroup = 256u;  // kPmlGroup

void ScanChunkCounts(uint group);                 // compact_scan.glsl
void ScanGroupTotals(uint invocation, uint slot);  // compact_scan.glsl

bool Kept(uint e) {
  if (u_kind == 0u) return remap[labels[e]] != labels[e];
  if (u_kind == 2u) return labels[face_edges[2u * e]] != labels[face_edges[2u * e + 1u]];
  return remap[edges_in[2u * e]] != remap[edges_in[2u * e + 1u]];
}

void main() {
  uint i = LinearInvocationIndex();
  if (u_phase == 1u) {
    ScanChunkCounts(i);
    return;
  }
  if (u_phase == 2u) {
    ScanGroupTotals(i, u_slot);
    return;
  }
  uint begin = i * kChunk;
  if (begin >= u_count) return;
  uint end = min(begin + kChunk, u_count);
  if (u_phase == 0u) {
    uint count = 0u;
    for (uint e = begin; e < end; ++e) count += Kept(e) ? 1u : 0u;
    chunk_count[i] = count;
    return;
  }
  uint at = chunk_count[i] + group_total[i / kGroup];
  for (uint e = begin; e < end; ++e) {
    if (!Kept(e)) continue;
    if (u_kind == 0u) {
      uint old_label = labels[e];
      uint new_label = remap[old_label];
      triplets[3u * at] = e;
      triplets[3u * at + 1u] = new_label;
      triplets[3u * at + 2u] = old_label;
      labels[e] = new_label;
    } else if (u_kind == 2u) {
      edges_out[2u * at] = labels[face_edges[2u * e]];
      edges_out[2u * at + 1u] = labels[face_edges[2u * e + 1u]];
    } else {
      edges_out[2u * at] = remap[edges_in[2u * e]];
      edges_out[2u * at + 1u] = remap[edges_in[2u * e + 1u]];
    }
    ++at;
  }
}
