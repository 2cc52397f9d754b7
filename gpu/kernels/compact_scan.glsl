// The scan phases of a stream compaction in chunks of kChunk elements and groups of
// kGroup chunks, shared by pml_compact.glsl and voxel_start.glsl: appended after the
// kernel, which declares chunk_count (one count per chunk), group_total (one per group),
// counters, u_count, kGroup and these two functions.

// Group `group`'s chunk counts (of u_count chunks) scanned exclusively in place, the
// group's total to group_total[group].
void ScanChunkCounts(uint group) {
  uint begin = group * kGroup;
  if (begin >= u_count) return;
  uint end = min(begin + kGroup, u_count);
  uint sum = 0u;
  for (uint c = begin; c < end; ++c) {
    uint count = chunk_count[c];
    chunk_count[c] = sum;
    sum += count;
  }
  group_total[group] = sum;
}

// The u_count group totals scanned exclusively in place by one invocation, the grand
// total to counters[slot].
void ScanGroupTotals(uint invocation, uint slot) {
  if (invocation != 0u) return;
  uint sum = 0u;
  for (uint g = 0u; g < u_count; ++g) {
    uint total = group_total[g];
    group_total[g] = sum;
    sum += total;
  }
  counters[slot] = sum;
}
