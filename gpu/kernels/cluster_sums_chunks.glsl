// SumByCluster (cluster_sums.h), pass 2 of 3: one invocation per chunk of kChunk
// consecutive elements in label order. Sums each label run inside the chunk in order, in
// fp64; writes a run that lies wholly inside the chunk as its cluster's sum, and the
// chunk's first and last runs as its head and tail partials (the cluster pass adds those
// of clusters that span chunks). After the prelude of gpu/context/compute.h.
layout(std430, binding = 0) readonly buffer Values { double values[]; };           // D per element
layout(std430, binding = 1) readonly buffer Order { uint order[]; };               // element ids by label
layout(std430, binding = 2) readonly buffer SortedLabels { uint sorted_labels[]; };  // label of order[i]
layout(std430, binding = 3) readonly buffer ClusterBegin { uint cluster_begin[]; };  // k + 1 offsets
layout(std430, binding = 4) writeonly buffer Sums { double sums[]; };              // D per cluster
layout(std430, binding = 5) writeonly buffer Heads { double heads[]; };            // D per chunk
layout(std430, binding = 6) writeonly buffer Tails { double tails[]; };            // D per chunk
layout(location = 0) uniform uint u_count;   // elements
layout(location = 1) uniform uint u_values;  // D, values per element (<= kMaxValues)
const uint kChunk = 32u;                     // kClusterSumsChunk
const uint kMaxValues = 16u;                 // kMaxValuesPerElement

void main() {
  uint chunk = LinearInvocationIndex();
  uint begin = chunk * kChunk;
  if (begin >= u_count) return;
  uint end = min(begin + kChunk, u_count);
  double acc[kMaxValues];
  for (uint j = 0u; j < u_values; ++j) acc[j] = 0.0LF;
  uint label = sorted_labels[begin];
  uint run_begin = begin;
  for (uint i = begin; i <= end; ++i) {
    uint next = i < end ? sorted_labels[i] : 0xFFFFFFFFu;
    if (i == end || next != label) {
      // The run [run_begin, i) of `label` is complete.
      bool whole = cluster_begin[label] >= begin && cluster_begin[label + 1u] <= end;
      for (uint j = 0u; j < u_values; ++j) {
        if (whole) sums[label * u_values + j] = acc[j];
        if (run_begin == begin) heads[chunk * u_values + j] = acc[j];
        if (i == end) tails[chunk * u_values + j] = acc[j];
        acc[j] = 0.0LF;
      }
      if (i == end) break;
      label = next;
      run_begin = i;
    }
    uint first_value = order[i] * u_values;
    for (uint j = 0u; j < u_values; ++j) acc[j] += values[first_value + j];
  }
}
