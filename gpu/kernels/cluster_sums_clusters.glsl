// SumByCluster (cluster_sums.h), pass 3 of 3: one invocation per cluster. A cluster whose
// elements span several chunks is the tail partial of its first chunk, plus the head
// partials (whole chunk sums) of the chunks between, plus the head of its last chunk,
// added in that order in fp64; an empty cluster is zero; a cluster inside one chunk was
// written by the chunk pass. After the prelude of gpu/context/compute.h.
layout(std430, binding = 3) readonly buffer ClusterBegin { uint cluster_begin[]; };  // k + 1 offsets
layout(std430, binding = 4) buffer Sums { double sums[]; };                        // D per cluster
layout(std430, binding = 5) readonly buffer Heads { double heads[]; };             // D per chunk
layout(std430, binding = 6) readonly buffer Tails { double tails[]; };             // D per chunk
layout(location = 0) uniform uint u_clusters;  // k
layout(location = 1) uniform uint u_values;    // D (<= kMaxValues)
const uint kChunk = 32u;                       // kClusterSumsChunk
const uint kMaxValues = 16u;                   // kMaxValuesPerElement

void main() {
  uint cluster = LinearInvocationIndex();
  if (cluster >= u_clusters) return;
  uint begin = cluster_begin[cluster];
  uint end = cluster_begin[cluster + 1u];
  if (begin == end) {
    for (uint j = 0u; j < u_values; ++j) sums[cluster * u_values + j] = 0.0LF;
    return;
  }
  uint first = begin / kChunk;
  uint last = (end - 1u) / kChunk;
  if (first == last) return;
  double acc[kMaxValues];
  for (uint j = 0u; j < u_values; ++j) acc[j] = tails[first * u_values + j];
  for (uint chunk = first + 1u; chunk <= last; ++chunk) {
    for (uint j = 0u; j < u_values; ++j) acc[j] += heads[chunk * u_values + j];
  }
  for (uint j = 0u; j < u_values; ++j) sums[cluster * u_values + j] = acc[j];
}
