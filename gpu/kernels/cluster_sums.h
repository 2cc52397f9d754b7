// Cluster sums on the GPU: for every cluster, the sum of its elements' additive data (the
// energy's face sums: area, area * centroid, area * |centroid|^2 for CVD; area * normal
// for the planar energy; ...), the quantity every energy and proxy is computed from.
//
// Method: a segmented reduction after a sort by label, in fp64 throughout (no atomics: no
// 64-bit atomics on llvmpipe, and float atomics would lose precision at 10^6 elements).
//   1. sort      a counting sort of the element ids by label, on the host (O(n + k));
//                `order` and the cluster offsets go to the GPU
//   2. chunks    one invocation per kClusterSumsChunk consecutive sorted elements sums
//                each label run inside its chunk in element order; a run that lies wholly
//                inside the chunk is the cluster's sum, the chunk's first and last runs
//                are also kept as the chunk's head and tail partials
//   3. clusters  one invocation per cluster that spans chunks adds the tail of its first
//                chunk, the heads (whole sums) of the chunks between and the head of its
//                last chunk; an empty cluster gets zeros
// Precision: every cluster's value is a sequential fp64 sum of at most kClusterSumsChunk
// terms per chunk plus one sequential fp64 sum over its chunks' partials, so its error is
// at most (kClusterSumsChunk + chunks of the cluster) * 2^-53 times the sum of the
// absolute values of its terms (the standard bound for recursive summation; it does not
// grow with the cluster count). The tests check a relative 1e-12 of that sum of absolute
// values against fp64 CPU sums on 10^6 faces with areas over twelve orders of magnitude.
//
// Memory (bytes on the GPU, see ClusterSumsMemoryBound): the values (8 * values_per_element
// per element), sorted labels and order (8 per element), cluster offsets (4 per cluster),
// the sums (8 * values_per_element per cluster) and two partials per chunk. Each must fit
// one storage buffer (RESOURCE_EXHAUSTED otherwise); there is no chunking of the input.
#ifndef MLCLUST_GPU_KERNELS_CLUSTER_SUMS_H_
#define MLCLUST_GPU_KERNELS_CLUSTER_SUMS_H_

#include <cstdint>
#include <cstring>
#include <span>
#include <type_traits>
#include <vector>

#include "absl/status/statusor.h"
#include "core/base/status_macros.h"
#include "gpu/context/gl_context.h"

namespace mlclust::gpu {

// Sorted elements per invocation of the chunk pass.
inline constexpr uint32_t kClusterSumsChunk = 32;
// The most doubles per element (MWCVD's and the sphere's sums have 9).
inline constexpr uint32_t kMaxValuesPerElement = 16;

// sums[c * values_per_element + j] = sum over elements i with labels[i] == c of
// values[i * values_per_element + j], for c < num_clusters (empty clusters: 0). Runs the
// passes "cluster sums" (gpu/context/pass.h names them in errors). Returns
//   INVALID_ARGUMENT if values_per_element is 0 or above kMaxValuesPerElement, values.size()
//     is not labels.size() * values_per_element, a label is >= num_clusters, or there are
//     2^31 elements or more;
//   RESOURCE_EXHAUSTED if a buffer exceeds context.max_storage_buffer_bytes() or GPU memory
//     runs out; FAILED_PRECONDITION on a thread other than the context's; INTERNAL on GL
//     errors.
absl::StatusOr<std::vector<double>> SumByCluster(GlContext& context, std::span<const double> values,
                                                 uint32_t values_per_element,
                                                 std::span<const uint32_t> labels,
                                                 uint32_t num_clusters);

// The CPU reference: the same sums, accumulated in element order in fp64. Expects valid
// inputs (asserted).
std::vector<double> SumByClusterCpu(std::span<const double> values, uint32_t values_per_element,
                                    std::span<const uint32_t> labels, uint32_t num_clusters);

// The bytes SumByCluster allocates on the GPU.
uint64_t ClusterSumsMemoryBound(uint64_t num_elements, uint32_t values_per_element,
                                uint32_t num_clusters);

// The energy's cluster sums (Energy::Sums for every cluster id below num_clusters) from its
// face sums, through SumByCluster. For energies whose Sums are made of doubles only (every
// mesh energy in core/energy/energies.h).
template <typename Energy>
absl::StatusOr<std::vector<typename Energy::Sums>> EnergyClusterSums(
    GlContext& context, const Energy& energy, std::span<const uint32_t> labels,
    uint32_t num_clusters) {
  using Sums = typename Energy::Sums;
  static_assert(std::is_trivially_copyable_v<Sums> && sizeof(Sums) % sizeof(double) == 0);
  constexpr uint32_t kValues = sizeof(Sums) / sizeof(double);
  static_assert(kValues <= kMaxValuesPerElement);
  std::vector<double> values(labels.size() * kValues);
  for (size_t i = 0; i < labels.size(); ++i) {
    std::memcpy(&values[i * kValues], &energy.face_sums(static_cast<uint32_t>(i)), sizeof(Sums));
  }
  MLCLUST_ASSIGN_OR_RETURN(std::vector<double> sums,
                           SumByCluster(context, values, kValues, labels, num_clusters));
  std::vector<Sums> out(num_clusters);
  std::memcpy(out.data(), sums.data(), sizeof(Sums) * num_clusters);
  return out;
}

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_KERNELS_CLUSTER_SUMS_H_
